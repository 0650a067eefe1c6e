"""Every shipped scenario plans (sampling planner) and passes the independent verifier."""

from __future__ import annotations

from pathlib import Path

import pytest

from proxplan.cli import main
from proxplan.planfile import load_scenario, write_plan
from proxplan.planner import plan_scenario
from proxplan.verify import verify_plan

SCENARIOS = sorted((Path(__file__).resolve().parents[2] / "scenarios").glob("*.yaml"))
REQUIRED = {"battery_swap", "package_handoff", "crossing_4", "swap_8", "corridor_stack"}


def test_the_required_scenarios_are_shipped():
    assert REQUIRED <= {p.stem for p in SCENARIOS}


@pytest.mark.parametrize("path", SCENARIOS, ids=lambda p: p.stem)
def test_shipped_scenario_plans_and_verifies(path, tmp_path, capsys):
    scenario = load_scenario(path)
    plan = plan_scenario(scenario, method="sampling", seed=0)
    violations = verify_plan(plan, scenario)
    assert violations == [], "\n".join(map(str, violations))
    write_plan(plan, tmp_path)
    assert main(["verify", str(tmp_path / "plan.json")]) == 0  # `proxplan verify` on the written file
    assert "PASS" in capsys.readouterr().out
    assert set(plan.vehicles) == set(scenario.vehicles)
    assert plan.metrics["max_authority_usage"] <= scenario.limits.authority_fraction
    assert plan.metrics["makespan_s"] > 0
