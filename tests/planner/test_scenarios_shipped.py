"""Every shipped scenario plans (sampling planner) and passes the independent verifier."""

from __future__ import annotations

from pathlib import Path

import pytest

from proxplan.cli import main
from proxplan.planfile import load_scenario, read_plan
from proxplan.verify import verify_plan

SCENARIOS = sorted((Path(__file__).resolve().parents[2] / "scenarios").glob("*.yaml"))
REQUIRED = {"battery_swap", "package_handoff", "crossing_4", "swap_8", "corridor_stack"}


def test_the_required_scenarios_are_shipped():
    assert REQUIRED <= {p.stem for p in SCENARIOS}


@pytest.mark.parametrize("path", SCENARIOS, ids=lambda p: p.stem)
def test_shipped_scenario_plans_and_verifies(path, shipped_plans, capsys):
    """The plan is the session's ``shipped_plans`` (tests/conftest.py: ``proxplan plan --method sampling``, seed
    0, in a fresh process, which plans as this process would: tests/planner/test_seed_per_search.py); the
    export tests export the same plans."""
    scenario = load_scenario(path)
    plan = read_plan(shipped_plans[path.stem])
    violations = verify_plan(plan, scenario)
    assert violations == [], "\n".join(map(str, violations))
    assert main(["verify", str(shipped_plans[path.stem] / "plan.json")]) == 0  # `proxplan verify` on the written file
    assert "PASS" in capsys.readouterr().out
    assert set(plan.vehicles) == set(scenario.vehicles)
    assert plan.metrics["max_authority_usage"] <= scenario.limits.authority_fraction
    assert plan.metrics["makespan_s"] > 0
