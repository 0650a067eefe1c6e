"""Same scenario, same seed, same plan, in any process: every OMPL search seeds the generators it
creates from its own seed (proxplan.planner.sampling.termination.seed_search), so a plan does not
depend on what the same process planned before."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np

from proxplan.planfile import load_scenario
from proxplan.planner import plan_scenario

SCENARIOS = Path(__file__).resolve().parents[2] / "scenarios"

_FRESH = """
import sys
import numpy as np
from proxplan.planfile import load_scenario
from proxplan.planner import plan_scenario
plan = plan_scenario(load_scenario(sys.argv[1]), method="sampling", seed=0)
np.savez(sys.argv[2], **{name: tr.position_m for name, tr in plan.vehicles.items()}, t_s=plan.t_s)
"""


def test_battery_swap_after_other_plans_equals_a_fresh_process_plan_to_the_bit(tmp_path):
    for other in ("crossing_4.yaml", "dock_side.yaml"):  # searches before it in this process
        plan_scenario(load_scenario(SCENARIOS / other), method="sampling", seed=3)
    here = plan_scenario(load_scenario(SCENARIOS / "battery_swap.yaml"), method="sampling", seed=0)
    out = tmp_path / "fresh.npz"
    subprocess.run(
        [sys.executable, "-c", _FRESH, str(SCENARIOS / "battery_swap.yaml"), str(out)],
        check=True, cwd=tmp_path, capture_output=True,
    )  # fmt: skip
    fresh = np.load(out)
    assert np.array_equal(fresh["t_s"], here.t_s)
    for name, tr in here.vehicles.items():
        assert np.array_equal(fresh[name], tr.position_m), name
