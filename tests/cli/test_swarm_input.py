"""Bad swarm input on `proxplan plan`: one line naming the vehicles, exit 2, within seconds (the
pair checks are one cKDTree query; a 1001-vehicle file is rejected before any vehicle is built)."""

from __future__ import annotations

import time

from proxplan.planfile import MAX_VEHICLES
from proxplan.planner.formations import grid_reshuffle


def _one_line(res, *needles: str) -> None:
    assert res.returncode == 2, (res.returncode, res.stderr)
    assert "Traceback" not in res.stderr and res.stderr.count("\n") == 1, res.stderr
    for needle in needles:
        assert needle in res.stderr, res.stderr


def test_no_vehicles(proxplan, write_yaml, tmp_path):
    doc = grid_reshuffle(4)
    doc["vehicles"] = {}
    res = proxplan("plan", write_yaml(doc), "--out", tmp_path / "out")
    _one_line(res, "vehicles", "at least one vehicle")
    assert not (tmp_path / "out").exists()


def test_too_many_vehicles_is_rejected_quickly(proxplan, write_yaml, tmp_path):
    path = write_yaml(grid_reshuffle(MAX_VEHICLES + 1))
    t0 = time.perf_counter()
    res = proxplan("plan", path, "--out", tmp_path / "out")
    _one_line(res, f"at most {MAX_VEHICLES} vehicles", f"got {MAX_VEHICLES + 1}")
    assert time.perf_counter() - t0 < 60  # generous: the shared test machine; bench for speed


def test_starts_closer_than_the_separation_name_both_vehicles(proxplan, write_yaml, tmp_path):
    doc = grid_reshuffle(100)
    a = doc["vehicles"]["v010"]["start"]
    doc["vehicles"]["v011"]["start"] = [a[0] + 0.1, a[1], a[2]]
    res = proxplan("plan", write_yaml(doc), "--out", tmp_path / "out", "--method", "sampling")
    _one_line(res, "vehicles.v010.start", "vehicles.v011.start", "0.100 m apart")


def test_goal_inside_another_goals_cutoff_names_both(proxplan, write_yaml, tmp_path):
    doc = grid_reshuffle(100, types=["crazyflie-2.1"])
    g = doc["vehicles"]["v020"]["goal"]
    doc["vehicles"]["v021"]["goal"] = [g[0] + 0.05, g[1], g[2] + 0.8]
    res = proxplan("plan", write_yaml(doc), "--out", tmp_path / "out", "--method", "swarm")
    _one_line(res, "vehicles.v020.goal", "cut-off of vehicles.v021.goal")


def test_two_vehicles_of_one_type_with_the_same_goal_under_by_type(proxplan, write_yaml, tmp_path):
    doc = grid_reshuffle(6, types=["crazyflie-2.1"])
    doc["assign_goals"] = "by_type"
    doc["vehicles"]["v003"]["goal"] = list(doc["vehicles"]["v001"]["goal"])
    res = proxplan("plan", write_yaml(doc), "--out", tmp_path / "out")
    _one_line(res, "vehicles.v001.goal", "vehicles.v003.goal", "assign_goals: by_type")
    assert not (tmp_path / "out").exists()


def test_unknown_assign_goals_value_names_the_key(proxplan, write_yaml, tmp_path):
    doc = grid_reshuffle(4)
    doc["assign_goals"] = "nearest"
    res = proxplan("plan", write_yaml(doc), "--out", tmp_path / "out")
    _one_line(res, "assign_goals", "by_type", "nearest")
    assert not (tmp_path / "out").exists()


def test_a_hovering_vehicle_under_by_type_keeps_its_task_and_the_plan_says_so(proxplan, write_yaml, tmp_path):
    import json

    doc = grid_reshuffle(4, types=["crazyflie-2.1"])
    doc["assign_goals"] = "by_type"
    xs = [-0.9, -0.3, 0.3, 0.9]
    doc["vehicles"] = {  # a row moves 1 m sideways in reversed order; v000 hovers where it is
        f"v{i:03d}": {"type": "crazyflie-2.1", "start": [xs[i], -0.5, 1.5], "goal": [xs[-1 - i], 0.5, 1.5]}
        for i in range(4)
    }
    hover = doc["vehicles"]["v000"]
    hover.pop("goal")
    hover["hover"] = True
    res = proxplan("plan", write_yaml(doc), "--out", tmp_path / "out", "--method", "sampling", "--json")
    assert res.returncode == 0, res.stderr
    plan = json.loads((tmp_path / "out" / "plan.json").read_text())
    record = plan["metrics"]["assignment"]
    assert record["fixed"] == {"v000": "hovers"}
    assert sorted(record["goal_of"]) == ["v001", "v002", "v003"]
    # goals at x = 0.3, -0.3, -0.9 for starts at -0.3, 0.3, 0.9: one slot over each (0.6 m sideways
    # for all) beats straight across (1.8 m for v003): the bottleneck first
    assert record["goal_of"] == {"v001": "v003", "v002": "v002", "v003": "v001"}
    assert plan["metrics"]["assignment_lower_bound_s"] > 0.0


def test_a_search_stopped_by_max_time_is_not_found_not_infeasible(proxplan, write_yaml, tmp_path):
    import json

    doc = grid_reshuffle(16)  # crossing paths: the straight step does not solve it, a search must run
    res = proxplan(
        "plan", write_yaml(doc), "--out", tmp_path / "out", "--method", "swarm", "--max-time", "0.001", "--json"
    )
    assert res.returncode == 3, (res.returncode, res.stderr)
    assert "Traceback" not in res.stderr and "not found" in res.stderr and "infeasible" not in res.stderr
    report = json.loads(res.stdout)
    assert report["found"] is False and report["feasible"] is None
    assert not (tmp_path / "out").exists()


def test_the_cli_offers_exactly_the_planner_methods():
    from proxplan.commands.plan import METHOD_CHOICES
    from proxplan.planner import METHODS

    assert METHOD_CHOICES == METHODS
