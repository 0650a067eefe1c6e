"""A three-high stack (scenarios/three_high_stack.yaml): planner, plan file and verifier evaluate the
same multi-source model (proxplan.costmaps.sources_wrench, proxplan.physics.stack), not a per-pair sum."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from proxplan.costmaps import pair_wrench, sources_wrench
from proxplan.physics import authority_usage
from proxplan.planfile import load_scenario
from proxplan.planner import plan_scenario
from proxplan.verify import verify_plan, wrench_along_plan

SCENARIO = Path(__file__).resolve().parents[2] / "scenarios" / "three_high_stack.yaml"


def _final_usages(scenario) -> tuple[float, float]:
    """(multi-source usage, per-pair-sum usage) of 'bottom' at its goal under 'top' and 'middle'."""
    bottom = scenario.vehicles["bottom"]
    goal = scenario.final_position_m("bottom")
    src = [(scenario.vehicles[n].vehicle, (goal - scenario.final_position_m(n))[None, :]) for n in ("top", "middle")]
    f, q = sources_wrench(bottom.vehicle, src, scenario.model_options)
    pairs = [pair_wrench(v, bottom.vehicle, o, scenario.model_options) for v, o in src]
    f_sum, q_sum = sum(p[0] for p in pairs), sum(p[1] for p in pairs)
    return float(authority_usage(bottom.vehicle, f, q)[0]), float(authority_usage(bottom.vehicle, f_sum, q_sum)[0])


def test_planner_and_verifier_agree_on_the_stack() -> None:
    scenario = load_scenario(SCENARIO)
    stack, pairwise = _final_usages(scenario)
    assert stack < 0.8 * pairwise  # the middle vehicle shields the bottom one from the top jet
    plan = plan_scenario(scenario, method="sampling", seed=0)
    assert verify_plan(plan, scenario) == []
    along = wrench_along_plan(plan, scenario, t_s=plan.t_s[-1:])["bottom"]
    assert along.usage[0] == pytest.approx(stack, rel=1e-9)
    np.testing.assert_allclose(plan.vehicles["bottom"].disturbance_force_N[-1], along.force_N[0], rtol=1e-9)
