"""Searches remembered by what they were searched against (proxplan.planner.swarm.memo), and the
second order of prioritised planning not run when it is the same pass (proxplan.planner.swarm.prioritised_stage)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from proxplan.planfile import scenario_from_dict
from proxplan.planner.formations import LAYOUTS, formation_change
from proxplan.planner.sampling.ordering import lower_bound_makespan_s
from proxplan.planner.swarm import SwarmOptions, swarm_problem, swarm_timed
from proxplan.planner.swarm.memo import Memo
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.prioritised_stage import ORDERS, horizon_steps
from proxplan.planner.swarm.priority import plan_one, prioritized_tracks
from proxplan.planner.swarm.priority_options import PriorityOptions
from proxplan.planner.swarm.reserve import predicted_track, reserved_track
from proxplan.planner.swarm.wave import wave_route

HORIZON = 1200


def _problem(layout: str, n: int):
    sc = scenario_from_dict(LAYOUTS[layout](n), label="test scenario")
    return sc, swarm_problem(sc)


def test_content_key_is_the_set_of_tracks_not_their_order():
    """Two occupancies holding the same tracks put in different orders (and one reached by putting,
    replacing and removing) have the same key; a track changed by one grid step, or another
    vehicle's track, changes it; so does the horizon."""
    _, problem = _problem("grid", 16)
    tracks = [predicted_track(problem, a, hold_s=1.0) for a in range(8)]
    one = Occupancy(problem, tracks, HORIZON)
    other = Occupancy(problem, tracks[::-1], HORIZON)
    assert one.content_key() == other.content_key()
    churned = Occupancy(problem, [reserved_track(problem, a) for a in range(10)], HORIZON)
    for tr in tracks:
        churned.put(tr)
    churned.remove(8)
    churned.remove(9)
    assert churned.content_key() == one.content_key()
    late = predicted_track(problem, 3, hold_s=1.025)  # one grid step later
    changed = Occupancy(problem, [late if tr.agent == 3 else tr for tr in tracks], HORIZON)
    assert changed.content_key() != one.content_key()
    more = Occupancy(problem, [*tracks, reserved_track(problem, 9)], HORIZON)
    assert more.content_key() != one.content_key()
    assert Occupancy(problem, tracks, HORIZON + 1).content_key() != one.content_key()


def test_a_recalled_search_equals_the_search():
    """Every vehicle of grid-16 planned against the others' predictions: the answers given back by
    the memo (asked again on a second occupancy of the same tracks, put in reverse order) equal a
    search on a problem whose memo keeps nothing, route and track alike."""
    _, problem = _problem("grid", 16)
    tracks = [predicted_track(problem, a, hold_s=1.0) for a in range(problem.n_agents)]
    plain = replace(problem)
    object.__setattr__(plain, "memo", Memo(0))
    occ_a, occ_b = Occupancy(problem, tracks, HORIZON), Occupancy(problem, tracks[::-1], HORIZON)
    occ_p = Occupancy(plain, tracks, HORIZON)
    routed = 0
    for a in range(problem.n_agents):
        for occ in (occ_a, occ_b, occ_p):
            occ.remove(a)
        s, g = problem.starts_m[a], problem.goals_m[a]
        first, again, fresh = (wave_route(o, a, s, g) for o in (occ_a, occ_b, occ_p))
        assert (first is None) == (again is None) == (fresh is None)
        if first is not None:
            routed += 1
            np.testing.assert_array_equal(first, fresh)
            np.testing.assert_array_equal(again, fresh)
        t1, t2, t3 = (plan_one(o, a, through=False) for o in (occ_a, occ_b, occ_p))
        assert (t1 is None) == (t2 is None) == (t3 is None)
        if t1 is not None:
            np.testing.assert_array_equal(t1.positions_m, t3.positions_m)
            np.testing.assert_array_equal(t2.positions_m, t3.positions_m)
        for occ in (occ_a, occ_b, occ_p):
            occ.put(tracks[a])
    assert routed > 0, "some vehicle must have a wavefront route"
    assert problem.memo.hits > 0 and plain.memo.hits == 0


def test_prioritised_passes_give_the_same_tracks_with_and_without_the_memo():
    """circle-16 fixed, both orders with reserved starts (the swarm layer's options): the same tracks
    with the memo as with a memo that keeps nothing, pass by pass, and the second order recalls
    searches of the first."""
    sc, problem = _problem("circle", 16)
    plain = replace(problem)
    object.__setattr__(plain, "memo", Memo(0))
    horizon = horizon_steps(lower_bound_makespan_s(sc))
    opts = PriorityOptions(
        max_repairs=math.ceil(0.25 * 16), max_plannings=96, hold_s=1.0, reserve_starts=True, through=False
    )
    for label in ("dependencies first", "longest first"):
        hits = problem.memo.hits
        got = prioritized_tracks(problem, ORDERS[label](problem), opts, horizon_steps=horizon)
        ref = prioritized_tracks(plain, ORDERS[label](plain), opts, horizon_steps=horizon)
        assert sorted(got.tracks) == sorted(ref.tracks) == list(range(problem.n_agents))
        for a in ref.tracks:
            np.testing.assert_array_equal(got.tracks[a].positions_m, ref.tracks[a].positions_m)
        assert (got.planned, got.repairs) == (ref.planned, ref.repairs)
        if label == "longest first":
            assert problem.memo.hits > hits, "the second order must recall searches of the first"


def test_an_order_equal_to_one_run_is_not_run_again_and_gives_the_same_plan():
    """pillar-16: both default orders are the same list of vehicles (no goal on another's start, so
    dependencies first is longest first). The stage runs the first only; the plan equals the one
    with the first order alone, and running the second order's pass really gives the same tracks."""
    sc = scenario_from_dict(formation_change(16), label="test scenario")
    problem = swarm_problem(sc)
    assert ORDERS["dependencies first"](problem) == ORDERS["longest first"](problem)
    both, info = swarm_timed(sc, SwarmOptions(workers=1, reserve_starts=True, makespan_repair=False))
    assert "longest first, hold 1 s: the same orders as dependencies first, not run again" in info.prioritised
    alone, _ = swarm_timed(
        sc, SwarmOptions(workers=1, reserve_starts=True, makespan_repair=False, orders=("dependencies first",))
    )
    for name in both:
        np.testing.assert_array_equal(both[name].knot_t_s, alone[name].knot_t_s)
        np.testing.assert_array_equal(both[name].knot_p_m, alone[name].knot_p_m)
    horizon = horizon_steps(lower_bound_makespan_s(sc))
    opts = PriorityOptions(max_repairs=4, max_plannings=96, hold_s=1.0, reserve_starts=True, through=False)
    first = prioritized_tracks(problem, ORDERS["dependencies first"](problem), opts, horizon_steps=horizon)
    plain = replace(problem)
    object.__setattr__(plain, "memo", Memo(0))
    second = prioritized_tracks(plain, ORDERS["longest first"](plain), opts, horizon_steps=horizon)
    for a in first.tracks:
        np.testing.assert_array_equal(first.tracks[a].positions_m, second.tracks[a].positions_m)


def test_orders_that_differ_are_both_run():
    """circle-16: the orders differ (every goal is another's start), so both passes are run."""
    sc = scenario_from_dict(LAYOUTS["circle"](16), label="test scenario")
    problem = swarm_problem(sc)
    assert ORDERS["dependencies first"](problem) != ORDERS["longest first"](problem)
    _, info = swarm_timed(sc, SwarmOptions(workers=1, reserve_starts=True, makespan_repair=False, passes=1))
    assert "not run again" not in info.prioritised
    assert info.prioritised.count("plannings") == 2


def test_static_answers_given_back_equal_the_recomputed_ones():
    """corridor-64 (a wall with a gap): the wavefront's static grid and the segment check given back
    by ``static_memo`` equal those computed afresh, for every vehicle's route box, and the wall
    really blocks some cells and some straight lines."""
    from proxplan.planner.swarm.wave_grid import CELL_M, margin_box, route_box, static_grid

    _, problem = _problem("corridor", 64)
    blocked_lines = 0
    for a in range(0, problem.n_agents, 4):
        s, g = problem.starts_m[a], problem.goals_m[a]
        got = problem.segment_free(s, g)
        assert problem.segment_free(s, g) == got == problem._segment_free(s, g, 0.02)
        blocked_lines += not got
        for lo, hi in (margin_box(problem, s, g), route_box(problem, s, g)):
            gx = lo[0] + np.arange(int(np.ceil((hi[0] - lo[0]) / CELL_M)) + 1) * CELL_M
            gy = lo[1] + np.arange(int(np.ceil((hi[1] - lo[1]) / CELL_M)) + 1) * CELL_M
            z = 0.5 * (s[2] + g[2])
            key = ("wave grid", np.asarray(lo, dtype=float).tobytes(), gx.size, gy.size, float(z))
            first = problem.static_memo.get(key, lambda gx=gx, gy=gy, z=z: static_grid(problem, gx, gy, z))
            again = problem.static_memo.get(key, lambda: np.zeros(1, dtype=bool))
            assert again is first
            np.testing.assert_array_equal(first, static_grid(problem, gx, gy, z))
    assert blocked_lines > 0
    assert problem.static_memo.hits > 0


def test_static_grid_equals_the_point_wise_test():
    """The static grid tested per axis equals ``static_free`` at every point, on corridor-64's whole
    free box (two wall boxes) at two heights."""
    from proxplan.planner.swarm.wave_grid import CELL_M, static_grid

    _, problem = _problem("corridor", 64)
    lo, hi = problem.lo_m, problem.hi_m
    gx = lo[0] + np.arange(int(np.ceil((hi[0] - lo[0]) / CELL_M)) + 1) * CELL_M
    gy = lo[1] + np.arange(int(np.ceil((hi[1] - lo[1]) / CELL_M)) + 1) * CELL_M
    X, Y = np.meshgrid(gx, gy, indexing="ij")
    for z in (1.0, 2.5):
        ref = np.ones(X.shape, dtype=bool)
        for fx, fy in ((0, 0), (1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (1, -1), (-1, 1), (-1, -1)):
            for f in (0.25, 0.5):
                pts = np.stack([X + f * fx * CELL_M, Y + f * fy * CELL_M, np.full_like(X, z)], axis=-1)
                ref &= problem.static_free(pts)
        np.testing.assert_array_equal(static_grid(problem, gx, gy, z), ref)
        assert ref.any() and not ref.all()
