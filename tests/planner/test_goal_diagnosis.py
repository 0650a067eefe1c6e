"""The tube-aware goal check (proxplan.planner.checks.precheck.check_goal_tubes): a goal clear at rest but
inside another vehicle's keep-out grown by the tracking tube is reported before any search, with
the other vehicle, by how much, and the nearest goal clear of it (which then passes the check)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from proxplan.planfile import load_scenario, scenario_from_dict
from proxplan.planner import InfeasibleError
from proxplan.planner.checks.precheck import check_goal_tubes, check_starts_and_goals

ROOT = Path(__file__).resolve().parents[2]


def _stack(goal, tube=0.06):
    return scenario_from_dict(
        {
            "name": "goal-edge",
            "workspace": {"min": [-1.5, -1.5, 0], "max": [1.5, 1.5, 2]},
            "limits": {"authority_fraction": 0.25, "min_separation_m": 0.2, "tracking_margin_m": tube},
            "vehicles": {
                "top": {"type": "crazyflie-parrot", "start": [0, 0, 1.0], "hover": True},
                "low": {"type": "crazyflie-2.1", "start": [-0.8, 0.3, 0.6], "goal": list(goal)},
            },
        }
    )


def test_goal_on_the_cutoff_edge_is_named_with_the_nearest_clear_goal():
    scenario = _stack([0.14, 0.0, 0.6])  # the old neural-swarm-stack goal
    check_starts_and_goals(scenario, mode="downwash")  # clear at rest
    with pytest.raises(InfeasibleError) as info:
        check_goal_tubes(scenario, mode="downwash")
    err = info.value
    assert err.vehicle == "low" and "top" in err.constraint
    d = err.details
    assert d["kind"] == "goal-in-tube" and d["other_vehicle"] == "top" and d["tracking_margin_m"] == 0.06
    suggested = np.asarray(d["suggested_goal_m"])
    assert d["shortfall_m"] == pytest.approx(np.linalg.norm(suggested - [0.14, 0.0, 0.6]), abs=1e-3)
    assert 0.0 < d["shortfall_m"] < 0.2
    assert str(np.round(suggested, 3).tolist()) in err.message and "\n" not in err.message
    # the suggestion passes the same check (no error), the original does not
    check_goal_tubes(_stack(suggested), mode="downwash")


def test_without_a_tube_the_same_goal_is_accepted():
    check_goal_tubes(_stack([0.14, 0.0, 0.6], tube=0.0), mode="downwash")


def test_the_shipped_neural_swarm_stack_has_no_special_case_and_a_clear_goal():
    path = ROOT / "scenarios" / "neural_swarm_stack.yaml"
    doc = yaml.safe_load(path.read_text())
    assert "tracking_margin_m" not in doc["limits"]
    scenario = load_scenario(path)
    assert scenario.limits.tracking_margin_m > 0.0
    check_goal_tubes(scenario, mode="downwash")


def test_cli_reports_the_diagnosis_in_one_line_and_json(tmp_path, capsys):
    from proxplan.cli import main

    doc = yaml.safe_load((ROOT / "scenarios" / "neural_swarm_stack.yaml").read_text())
    doc["vehicles"]["cf51"]["goal"] = [0.14, 0.0, 0.6]  # the old goal: on the cut-off edge ...
    doc["limits"]["tracking_margin_m"] = 0.05  # ... within the 5 cm tube it was moved for (1.9 cm since issue 31)
    path = tmp_path / "edge.yaml"
    path.write_text(yaml.safe_dump(doc))
    assert main(["plan", str(path), "--out", str(tmp_path / "out"), "--json", "--no-plot"]) == 1
    captured = capsys.readouterr()
    out = json.loads(captured.out)
    assert out["feasible"] is False and out["vehicle"] == "cf51"
    assert out["diagnosis"]["other_vehicle"] == "cf101" and len(out["diagnosis"]["suggested_goal_m"]) == 3
    assert len(captured.err.strip().splitlines()) == 1 and "vehicles.cf51.goal" in captured.err
    assert not (tmp_path / "out").exists()
