"""The streams-in-lanes diagnostic of benchmarks/why_128.py (``--flow`` and the final tracks' rests; round
23B, docs/planner.md "Stop 61, round 23B"): direction groups follow the headings, a lane route leaves the
others' starts and goals where an offset clears them, the flow timing is conflict-free and verifies, and a
rest is reported where the vehicle rests."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import why_128  # noqa: E402

from proxplan.planfile import scenario_from_dict  # noqa: E402
from proxplan.planner.formations import LAYOUTS  # noqa: E402
from proxplan.planner.swarm import swarm_problem  # noqa: E402
from proxplan.planner.swarm.occupancy import Occupancy  # noqa: E402
from proxplan.planner.swarm.tracks import GRID_DT_S, GridTrack  # noqa: E402
from proxplan.planner.timing import assemble_plan  # noqa: E402
from proxplan.planner.timing.profile import LineMove, rest_to_rest  # noqa: E402
from proxplan.verify import verify_plan  # noqa: E402

from .test_swarm_128_holding import _in_line  # noqa: E402  (one height, far flies through near's start and goal)

HORIZON = 1200
FAR, NEAR = 0, 1


def test_direction_groups_follow_the_headings():
    corridor = swarm_problem(scenario_from_dict(LAYOUTS["corridor"](16), label="corridor-16"))
    groups = why_128.direction_groups(corridor)
    assert len(groups) == 2  # the west group flies east, the east group west
    by_sign = {int(np.sign(heading[0])): members for heading, members in groups}
    assert sorted(by_sign) == [-1, 1]
    assert by_sign[1] == list(range(0, 16, 2)) and by_sign[-1] == list(range(1, 16, 2))
    pillar = swarm_problem(scenario_from_dict(LAYOUTS["pillar"](16), label="pillar-16"))
    (heading, members), *rest = why_128.direction_groups(pillar)
    assert rest == [] and members == list(range(16)) and heading[0] > 0.99


def test_a_lane_route_leaves_the_line_that_passes_anothers_start_and_goal():
    """far's straight line passes near's start and goal; its lane route is offset so that it passes none,
    from its start to its goal through free space; near's line passes nobody's and stays straight."""
    _, problem = _in_line()
    routes, hits = why_128.lane_routes(problem, HORIZON)
    starts_hit, goals_hit, _ = hits[FAR]
    assert starts_hit == set() and goals_hit == set()
    far = routes[FAR]
    np.testing.assert_array_equal(far[0], problem.starts_m[FAR])
    np.testing.assert_array_equal(far[-1], problem.goals_m[FAR])
    assert len(far) > 2 and np.abs(far[:, 1]).max() > 0.5 * problem.reach_xy_m  # left the line y = 0
    assert all(problem.segment_free(p, q) for p, q in zip(far[:-1], far[1:], strict=True))
    assert len(routes[NEAR]) == 2 and hits[NEAR][:2] == (set(), set())


def test_keep_right_offsets_the_lane_to_the_right_of_the_heading_only():
    """far flies +x: its right is -y. Offset to its right only, its lane lies at y < 0; to its left only, y > 0."""
    _, problem = _in_line()
    for side, sign in ((1.0,), -1.0), ((-1.0,), 1.0):
        routes, hits = why_128.lane_routes(problem, HORIZON, side)
        assert hits[FAR][:2] == (set(), set())
        y = routes[FAR][1:-1, 1]
        assert (np.sign(y) == sign).all() and np.abs(y).min() > 0.5 * problem.reach_xy_m


def test_the_flow_timing_is_conflict_free_verifies_and_repeats():
    sc, problem = _in_line()
    routes, hits = why_128.lane_routes(problem, HORIZON)
    tracks, how = why_128.flow_timing(problem, routes, hits, HORIZON)
    assert how.startswith("all timed") and sorted(tracks) == [FAR, NEAR]
    occ = Occupancy(problem, list(tracks.values()), HORIZON)
    for a, tr in tracks.items():
        occ.remove(a)
        assert occ.conflicting_agents(tr) == set()
        occ.put(tr)
    timed = {problem.names[a]: tr.timed_path() for a, tr in tracks.items()}
    assert verify_plan(assemble_plan(sc, timed, method="swarm", notes=[]), sc) == []
    again, _ = why_128.flow_timing(problem, *why_128.lane_routes(problem, HORIZON), HORIZON)
    for a, tr in tracks.items():
        np.testing.assert_array_equal(tr.positions_m, again[a].positions_m)


def test_rests_are_reported_where_and_as_long_as_the_vehicle_rests():
    _, problem = _in_line()
    s, g = problem.starts_m[NEAR], problem.goals_m[NEAR]
    profile = rest_to_rest(float(np.linalg.norm(g - s)), problem.limits[NEAR], GRID_DT_S)
    track = GridTrack(NEAR, int(problem.type_index[NEAR]), s.copy(), [(40, LineMove(s, g, profile))])
    (rest,) = why_128._rests(track)
    t0, duration, where = rest
    # the 40 held steps, and the first samples of the move while it is still slower than a rest's speed
    assert t0 == 0.0 and 40 * GRID_DT_S <= duration < 40 * GRID_DT_S + 0.25
    np.testing.assert_array_equal(where, s)
    assert (
        why_128._rests(GridTrack(NEAR, int(problem.type_index[NEAR]), s.copy(), [(0, LineMove(s, g, profile))])) == []
    )
