"""`proxplan plan` / `proxplan verify` end to end: files, JSON, exit codes, messages."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]
DESIGN_VEHICLE_KEYS = {"type", "t_s", "position_m", "velocity_mps", "acceleration_mps2"}
DESIGN_METRICS = {"planning_time_s", "max_authority_usage", "min_separation_m", "makespan_s"}


def _run(*args, timeout=180):
    return subprocess.run(
        [sys.executable, "-m", "proxplan.cli", *map(str, args)],
        capture_output=True,
        text=True,
        timeout=timeout,
        cwd=ROOT,
    )


@pytest.fixture(scope="module")
def battery_plan(battery_swap_planned):
    """``proxplan plan scenarios/battery_swap.yaml --out OUT --method sampling --json`` in a fresh process: the
    session's run (tests/conftest.py, the same command; read-only here): (OUT, the finished process)."""
    return battery_swap_planned


def test_plan_writes_design_files_and_one_json_object(battery_plan):
    out, res = battery_plan
    report = json.loads(res.stdout)  # exactly one JSON object on stdout
    assert report["feasible"] and report["verify"]["passed"]
    doc = json.loads((out / "plan.json").read_text())
    assert {"scenario", "dt_s", "vehicles", "metrics"} <= set(doc)
    assert doc["scenario"] == "battery-swap"
    assert DESIGN_METRICS <= set(doc["metrics"])
    grids = []
    for name, v in doc["vehicles"].items():
        assert DESIGN_VEHICLE_KEYS <= set(v), name
        n = len(v["t_s"])
        assert len(v["position_m"]) == n and len(v["position_m"][0]) == 3
        grids.append(v["t_s"])
    assert all(g == grids[0] for g in grids)  # one common time grid
    assert doc["scenario_file"].endswith("battery_swap.yaml") and doc["scenario_spec"]["name"] == "battery-swap"
    assert any("invalid zone" in n for n in doc["notes"])  # the dock's invalid-zone crossing is reported
    assert (out / "plan.png").stat().st_size > 10_000
    assert "verify: PASS" in (out / "summary.txt").read_text()


def test_verify_passes_standalone_and_fails_on_a_tampered_plan(battery_plan, tmp_path):
    out, _ = battery_plan
    res = _run("verify", out / "plan.json")
    assert res.returncode == 0 and "PASS" in res.stdout
    doc = json.loads((out / "plan.json").read_text())
    # move the shuttle 0.6 m under the carrier for the whole plan: downwash + separation + dock
    doc["vehicles"]["shuttle"]["position_m"] = [[0.0, 0.05, 0.9] for _ in doc["vehicles"]["shuttle"]["t_s"]]
    bad = tmp_path / "plan.json"
    bad.write_text(json.dumps(doc))
    res = _run("verify", bad, "--json")
    assert res.returncode == 1
    report = json.loads(res.stdout)
    kinds = {(v["vehicle"], v["kind"]) for v in report["violations"]}
    assert ("shuttle", "authority") in kinds and ("shuttle", "dock") in kinds
    assert all("t_s" in v for v in report["violations"])


def test_infeasible_scenario_names_vehicle_and_constraint(tmp_path):
    path = tmp_path / "infeasible.yaml"
    path.write_text(
        yaml.safe_dump(
            {
                "name": "infeasible",
                "workspace": {"min": [-3, -3, 0], "max": [3, 3, 4]},
                "limits": {"authority_fraction": 0.1},
                "vehicles": {
                    "small": {"type": "small-quad", "start": [0, 0, 1.2], "goal": [2, 0, 1.0]},
                    "big": {"type": "large-quad", "start": [0, 0, 2.0], "hover": True},
                },
            },
            sort_keys=False,
        )
    )
    res = _run("plan", path, "--out", tmp_path / "o", "--method", "sampling", "--json")
    assert res.returncode == 1
    report = json.loads(res.stdout)
    assert report["vehicle"] == "small" and "downwash of big" in report["constraint"]
    assert "infeasible" in res.stderr and "'small'" in res.stderr and "Traceback" not in res.stderr
    assert not (tmp_path / "o" / "plan.json").exists()


def test_goal_inside_a_hovering_vehicles_cutoff_is_a_user_error(tmp_path):
    """Issue 21: a goal inside another's cut-off zone is bad input (exit 2, one line, both named)."""
    path = tmp_path / "goal.yaml"
    path.write_text(
        yaml.safe_dump(
            {
                "name": "goal-under-hover",
                "workspace": {"min": [-3, -3, 0], "max": [3, 3, 4]},
                "limits": {"authority_fraction": 0.1},
                "vehicles": {
                    "big": {"type": "large-quad", "start": [0, 0, 2.0], "hover": True},
                    "small": {"type": "small-quad", "start": [2, 0, 1.0], "goal": [0, 0, 1.2]},
                },
            },
            sort_keys=False,
        )
    )
    res = _run("plan", path, "--out", tmp_path / "o", "--method", "sampling")
    assert res.returncode == 2 and res.stderr.count("\n") == 1 and "Traceback" not in res.stderr
    assert "vehicles.small.goal" in res.stderr and "vehicles.big.goal" in res.stderr
    assert not (tmp_path / "o").exists()


def test_bad_scenario_exits_2_with_one_line(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text(
        "workspace: {min: [0, 0, 0], max: [1, 1, 1]}\nvehicles:\n  a: {type: jumbo-jet, start: [0.5, 0.5, 0.5], hover: true}\n"
    )
    res = _run("plan", path, "--out", tmp_path / "o")
    assert res.returncode == 2
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and "vehicles.a.type" in lines[0] and "jumbo-jet" in lines[0] and str(path) in lines[0]


def test_verify_of_a_broken_file_is_a_user_error(tmp_path):
    bad = tmp_path / "plan.json"
    bad.write_text('{"scenario": "x", "dt_s": 0.1}')
    res = _run("verify", bad)
    assert res.returncode == 2 and "vehicles" in res.stderr and "Traceback" not in res.stderr


def test_help_for_both_commands():
    for cmd in ("plan", "verify"):
        res = _run(cmd, "--help")
        assert res.returncode == 0 and "usage" in res.stdout
