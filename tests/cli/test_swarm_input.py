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
    res = proxplan("plan", write_yaml(doc), "--out", tmp_path / "out", "--method", "roadmap")
    _one_line(res, "vehicles.v020.goal", "cut-off of vehicles.v021.goal")
