"""Space-time sampling planner and its constraint checks."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from proxplan.physics import BUILTIN_VEHICLES, VALIDITY_FACTOR_L, authority_usage, disturbance_wrench
from proxplan.planfile import scenario_from_dict
from proxplan.planner import DT_S
from proxplan.planner.checks.constraints import Track, build_checker
from proxplan.planner.sampling import GoalSpec, SamplingOptions, plan_space_time
from proxplan.planner.timing import common_grid, time_parameterize

ROOT = Path(__file__).resolve().parents[2]
LARGE, SMALL = BUILTIN_VEHICLES["large-quad"], BUILTIN_VEHICLES["small-quad"]


def _scenario(fraction=0.15):
    return scenario_from_dict(
        {
            "name": "s",
            "workspace": {"min": [-3, -3, 0], "max": [3, 3, 3.5]},
            "limits": {"authority_fraction": fraction, "min_separation_m": 0.3},
            "vehicles": {
                "big": {"type": "large-quad", "start": [0, 0, 2.0], "hover": True},
                "small": {"type": "small-quad", "start": [-2, 0.1, 0.9], "goal": [2, -0.1, 0.9]},
            },
        }
    )


def test_checker_downwash_agrees_with_the_model():
    sc = _scenario(fraction=0.1)
    checker = build_checker(sc, "small", [Track.static("big", LARGE, np.array([0, 0, 2.0]))])
    rng = np.random.default_rng(1)
    dz = rng.uniform(VALIDITY_FACTOR_L * LARGE.size_m + 0.05, 2.5, 400)
    r = rng.uniform(0.0, 0.6, 400)
    phi = rng.uniform(0, 2 * np.pi, 400)
    pts = np.column_stack([r * np.cos(phi), r * np.sin(phi), 2.0 - dz])
    verdict = [checker.conflict(*p, 0.0) for p in pts]
    w = disturbance_wrench(LARGE, SMALL, pts - np.array([0, 0, 2.0]))
    usage = authority_usage(SMALL, w.force_N, w.torque_Nm)
    ok = np.array([v is None for v in verdict])
    blocked = np.array([v == "downwash of big" for v in verdict])
    assert ok.any() and blocked.any()
    assert usage[ok].max() <= 0.1 + 0.01  # accepted states keep usage under the level
    assert usage[blocked].max() > 0.1  # and the cutoff does block where the model is over it


def test_invalid_zone_is_blocked_conservatively():
    sc = _scenario()
    checker = build_checker(sc, "small", [Track.static("big", LARGE, np.array([0, 0, 2.0]))])
    inside = checker.conflict(0.0, 0.3, 2.0 - 0.5, 0.0)  # dz = 0.5 m < 3 L, footprints overlap
    assert inside is not None and "big" in inside
    assert checker.conflict(0.0, 0.0, 2.0 + 0.5, 0.0) is None  # above the source: no downwash on it from big
    sep_only = build_checker(sc, "small", [Track.static("big", LARGE, np.array([0, 0, 2.0]))], mode="no-downwash")
    assert sep_only.conflict(0.0, 0.0, 1.4, 0.0) is None


def test_ellipsoid_mode_radii():
    sc = _scenario()
    track = [Track.static("big", LARGE, np.array([0, 0, 2.0]))]
    checker = build_checker(sc, "small", track, mode="ellipsoid", tube=False)
    r = LARGE.body_radius_m + SMALL.body_radius_m
    assert checker.conflict(0, 0, 2.0 - 2.9 * r, 0.0) is not None  # vertical radius 3 r
    assert checker.conflict(0, 0, 2.0 - 3.1 * r, 0.0) is None
    assert checker.conflict(1.05 * r, 0, 2.0, 0.0) is None  # horizontal radius r
    # the tracking tube (limits.tracking_margin_m) grows the radius by the tube
    tube = sc.limits.tracking_margin_m
    assert tube > 0.0
    with_tube = build_checker(sc, "small", track, mode="ellipsoid")
    assert with_tube.conflict(r + 0.5 * tube, 0, 2.0, 0.0) is not None
    assert with_tube.conflict(r + 1.5 * tube, 0, 2.0, 0.0) is None


def test_tube_grows_cutoff_and_separation():
    sc = _scenario()
    track = [Track.static("big", LARGE, np.array([0, 0, 2.0]))]
    plain = build_checker(sc, "small", track, tube=False)
    tubed = build_checker(sc, "small", track)
    tube = sc.limits.tracking_margin_m
    for dz in (0.4, 0.9, 1.5):
        rc = plain.rules[0].cutoff_m(plain.rules[0].cut_from_other, dz)
        if rc > 0.0:
            assert tubed.rules[0].cutoff_m(tubed.rules[0].cut_from_other, dz) >= rc + tube - 1e-12
    assert tubed.rules[0].separation_m == pytest.approx(plain.rules[0].separation_m + tube)


def test_moving_track_is_interpolated_in_time():
    tr = Track.from_arrays("m", SMALL, 0.5, np.array([[0, 0, 1], [1, 0, 1], [2, 0, 1]], dtype=float))
    np.testing.assert_allclose(tr.at(0.25), [0.5, 0, 1])
    np.testing.assert_allclose(tr.at(10.0), [2, 0, 1])  # holds the last sample


def test_space_time_plan_avoids_the_hovering_source_and_is_timed_validly():
    sc = _scenario(fraction=0.1)
    others = [Track.static("big", LARGE, sc.vehicles["big"].start_m)]
    checker = build_checker(sc, "small", others, margin_m=0.02)
    nominal = build_checker(sc, "small", others)
    task = sc.vehicles["small"]
    limits = task.kinematic_limits
    # the straight line passes right under the source: it must be rejected
    straight = np.linspace(task.start_m, task.goal_m, 60)
    assert any(nominal.conflict(*p, 0.0) for p in straight)
    path = None
    for seed in range(3):
        path = plan_space_time(
            checker,
            task.start_m,
            GoalSpec(task.goal_m, hold_until_s=5.0),
            limits,
            horizon_s=30.0,
            seed=seed,
            options=SamplingOptions(time_budget_s=2.0),
        )
        if path is not None:
            break
    assert path is not None
    assert np.all(np.diff(path.times_s) >= 0)
    tp = time_parameterize(path.waypoints_m, path.times_s, limits)
    t = common_grid(tp.duration_s, DT_S / 5)
    p, v, _ = tp.sample(t)
    assert all(nominal.conflict(*pi, float(ti)) is None for ti, pi in zip(t, p))
    np.testing.assert_allclose(p[-1], task.goal_m, atol=1e-6)
    assert np.linalg.norm(v, axis=1).max() <= task.max_speed_mps * (1 + 1e-6)


def test_dock_approach_point_is_outside_the_invalid_zone():
    sc = scenario_from_dict(
        {
            "workspace": {"min": [-3, -3, 0], "max": [3, 3, 4]},
            "vehicles": {
                "carrier": {"type": "large-quad", "start": [0, 0, 1.5], "hover": True},
                "shuttle": {
                    "type": "small-quad",
                    "start": [2, 1, 2.5],
                    "dock": {"with": "carrier", "offset": [0, 0, 0.3]},
                },
            },
        }
    )
    a, d = sc.dock_geometry("shuttle")
    np.testing.assert_allclose(d, [0, 0, 1.8])
    assert a[2] - 1.5 > VALIDITY_FACTOR_L * SMALL.size_m  # the carrier is outside the shuttle's invalid zone at A
    np.testing.assert_allclose(a[:2], 0.0)


def _plan_in_subprocess(tmp_path, seed, tag):
    out = tmp_path / tag
    res = subprocess.run(
        [
            sys.executable,
            "-m",
            "proxplan.cli",
            "plan",
            str(ROOT / "scenarios" / "crossing_4.yaml"),
            "--out",
            str(out),
            "--method",
            "sampling",
            "--seed",
            str(seed),
            "--no-plot",
            "--json",
        ],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=ROOT,
    )
    assert res.returncode == 0, res.stderr
    return json.loads((out / "plan.json").read_text())["vehicles"]


def test_same_seed_same_plan(tmp_path):
    a = _plan_in_subprocess(tmp_path, 3, "a")
    b = _plan_in_subprocess(tmp_path, 3, "b")
    assert a == b


def test_a_vehicle_whose_goal_is_its_start_starts_there_when_it_must_dodge():
    """The waiting search's roadmap keeps the start as node 0 even where it is the goal (it once
    dropped it with the goal's duplicates, and the plan began at a dodge point 0.3 m away)."""
    from proxplan.planner import plan_scenario
    from proxplan.verify import verify_plan

    doc = {
        "name": "stay-and-pass",
        "workspace": {"min": [-2.0, -2.0, 0.0], "max": [2.0, 2.0, 3.0]},
        "limits": {"authority_fraction": 0.3, "min_separation_m": 0.25},
        "vehicles": {
            "runner": {"type": "crazyflie-2.1", "start": [-1.2, 0.0, 1.5], "goal": [1.2, 0.0, 1.5]},
            "stayer": {"type": "crazyflie-2.1", "start": [0.0, 0.0, 1.5], "goal": [0.0, 0.0, 1.5]},
        },
    }
    scenario = scenario_from_dict(doc, label="stay-and-pass")
    plan = plan_scenario(scenario, method="sampling", seed=0)
    stayer = plan.vehicles["stayer"]
    assert np.allclose(stayer.position_m[0], [0.0, 0.0, 1.5], atol=1e-6)
    assert np.allclose(stayer.position_m[-1], [0.0, 0.0, 1.5], atol=0.05)
    assert verify_plan(plan, scenario) == []


def test_roadmap_nodes_start_first_goal_last_even_when_they_coincide():
    from proxplan.planner.sampling.roadmap import roadmap_nodes

    p = np.array([0.0, 0.0, 1.5])
    for end in (p, np.array([1.0, 0.5, 1.5])):
        nodes = roadmap_nodes(p, end, [], dodge_m=0.3, clearance_m=0.15)
        assert np.allclose(nodes[0], p) and np.allclose(nodes[-1], end)
        assert not any(np.allclose(q, end) for q in nodes[1:-1])  # no other copy of the goal


def test_the_sampling_planner_stops_on_its_count_budget_as_not_found():
    """``SamplingOptions.max_searches`` bounds the single-vehicle searches of a whole plan: with too
    small a budget the planner says "not found" (PlanNotFound), never "infeasible"; with enough, it
    plans the same scenario."""
    from proxplan.planner.errors import PlanNotFound
    from proxplan.planner.formations import grid_reshuffle
    from proxplan.planner.sampling import sampling_plan

    scenario = scenario_from_dict(grid_reshuffle(4, seed=1), label="test")
    with pytest.raises(PlanNotFound, match="budget of 2 single-vehicle searches"):
        sampling_plan(scenario, mode="downwash", seed=0, options=SamplingOptions(max_searches=2), progress=None)
    plan = sampling_plan(scenario, mode="downwash", seed=0, options=SamplingOptions(max_searches=40), progress=None)
    assert set(plan.vehicles) == set(scenario.vehicles)


def test_the_sampling_planner_stops_at_the_first_vehicle_that_arrives_no_earlier_than_beat_s():
    """``SamplingOptions.beat_s``: the plan is wanted only when it ends before that time. Given its own
    makespan the planner stops ("could not be shorter", PlanNotFound, never "infeasible") at the
    vehicle that sets it; given one grid step more it plans the same plan as without the option
    (the arrival it checks is the assembled plan's, on the same grid)."""
    from dataclasses import replace

    from proxplan.planner.errors import PlanNotFound
    from proxplan.planner.formations import grid_reshuffle
    from proxplan.planner.sampling import sampling_plan
    from proxplan.planner.timing.plan_grid import DT_S, moving_end_s, vehicle_arrival_s

    scenario = scenario_from_dict(grid_reshuffle(4, seed=1), label="test")
    options = SamplingOptions(max_searches=40)
    free = sampling_plan(scenario, mode="downwash", seed=0, options=options, progress=None)
    makespan = moving_end_s(free)
    last = {n for n, tr in free.vehicles.items() if vehicle_arrival_s(tr) >= makespan}  # those that set it
    with pytest.raises(PlanNotFound, match="could not be shorter") as stopped:
        sampling_plan(scenario, mode="downwash", seed=0, options=replace(options, beat_s=makespan), progress=None)
    assert len(stopped.value.vehicles) == 1 and stopped.value.vehicles[0] in last
    again = sampling_plan(
        scenario, mode="downwash", seed=0, options=replace(options, beat_s=makespan + DT_S), progress=None
    )
    for name, tr in free.vehicles.items():
        np.testing.assert_array_equal(tr.position_m, again.vehicles[name].position_m)
