"""The swarm layer's space-time hash (proxplan.planner.swarm.occupancy): its departure and hold
queries equal a brute-force check of every grid step against every other track, for straight
moves and flights through waypoints, with parked and vanishing (predicted) tracks."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.planfile import scenario_from_dict
from proxplan.planner.formations import grid_reshuffle
from proxplan.planner.swarm.occupancy import SAMPLING_GROWTH_M, Occupancy, _conflict
from proxplan.planner.swarm.priority import predicted_track
from proxplan.planner.swarm.problem import swarm_problem
from proxplan.planner.swarm.tracks import GRID_DT_S, GridTrack
from proxplan.planner.timing import CORNER_DEVIATION_M
from proxplan.planner.timing.profile import LineMove, RunMove, rest_to_rest

HORIZON = 260


@pytest.fixture(scope="module")
def world():
    problem = swarm_problem(scenario_from_dict(grid_reshuffle(9, seed=4), label="test"))
    rng = np.random.default_rng(7)
    me = int(np.argmax(np.linalg.norm(problem.goals_m - problem.starts_m, axis=1)))  # the queried vehicle
    me_s, me_g = problem.starts_m[me], problem.goals_m[me]
    tracks = []
    for a in range(problem.n_agents):
        if a == me:
            continue
        s, g = problem.starts_m[a], problem.goals_m[a]
        if a % 4 == 0:
            tracks.append(predicted_track(problem, a, hold_s=0.2 * a))
            continue
        mid = 0.5 * (s + g) + np.r_[rng.uniform(-0.4, 0.4, 2), 0.0]
        if a % 2:
            mv = RunMove(np.array([s, mid, g]), problem.limits[a], GRID_DT_S, deviation_m=CORNER_DEVIATION_M)
        else:
            mv = LineMove(s, g, rest_to_rest(float(np.linalg.norm(g - s)), problem.limits[a], GRID_DT_S))
        tr = GridTrack(a, int(problem.type_index[a]), s.copy(), [(int(rng.integers(0, 40)), mv)])
        # tracks ending beside the queried line park there (late departures are forbidden for good),
        # the others vanish at their end (so early and late departures stay open somewhere)
        tracks.append(
            tr if a % 3 == 1 and _line_distance(tr.end_m, me_s, me_g) > 0.5 else tr.vanishing(tr.arrival_step + 1)
        )
    return problem, tracks, me


def _line_distance(p, a, b) -> float:
    ab = b - a
    s = float(np.clip((p - a) @ ab / (ab @ ab), 0.0, 1.0))
    return float(np.linalg.norm(p - a - s * ab))


def _others_at(tracks, t):
    """(track, position, parked) of every other track present at step t."""
    for tr in tracks:
        if t < tr.arrival_step:
            yield tr, tr.positions_m[t], False
        elif t == tr.arrival_step and tr.vanishes:
            yield tr, tr.positions_m[t], False
        elif not tr.vanishes:
            yield tr, tr.end_m, True


def test_departures_equal_a_brute_force_check(world):
    problem, tracks, me = world
    occ = Occupancy(problem, tracks, HORIZON)
    s, g = problem.starts_m[me], problem.goals_m[me]
    lim = problem.limits[me]
    moves = [
        LineMove(s, g, rest_to_rest(float(np.linalg.norm(g - s)), lim, GRID_DT_S)),
        RunMove(np.array([s, 0.5 * (s + g) + [0.3, -0.2, 0.0], g]), lim, GRID_DT_S, deviation_m=CORNER_DEVIATION_M),
    ]
    for mv in moves:
        q = mv.positions()
        got = occ.forbidden_departures(me, q)
        want = np.zeros(HORIZON, dtype=bool)
        for d in range(HORIZON):
            for k in range(q.shape[0]):
                for tr, p, _ in _others_at(tracks, d + k):
                    ko = problem.keepouts[(int(problem.type_index[me]), tr.type)]
                    if _conflict(ko, (p - q[k])[None], False, SAMPLING_GROWTH_M)[0]:
                        want[d] = True
                        break
                if want[d]:
                    break
        assert want.any() and not want.all(), "the test world must constrain the move somewhere"
        np.testing.assert_array_equal(got, want)
        # a window of departures: only the segments that can forbid one in it are looked at, and
        # inside it the answer is the same
        for lo, hi in ((0, 40), (25, 90), (60, HORIZON)):
            part = occ.forbidden_departures(me, q, from_step=lo, until_step=hi)
            np.testing.assert_array_equal(part[lo:hi], want[lo:hi])


def test_holds_equal_a_brute_force_check(world):
    problem, tracks, me = world
    occ = Occupancy(problem, tracks, HORIZON)
    s, g = problem.starts_m[me], problem.goals_m[me]
    held_somewhere: list[bool] = []
    for w in (s, g, 0.5 * (s + g)):
        got = occ.forbidden_holds(me, w)
        want = np.zeros(HORIZON, dtype=bool)
        for t in range(HORIZON):
            for tr, p, parked in _others_at(tracks, t):
                rest = parked or not tr.moving[min(t, tr.arrival_step)]
                ko = problem.keepouts[(int(problem.type_index[me]), tr.type)]
                if _conflict(ko, (p - w)[None], rest, SAMPLING_GROWTH_M)[0]:
                    want[t] = True
                    break
        np.testing.assert_array_equal(got, want)
        held_somewhere.append(bool(want.any()))
    assert any(held_somewhere), "the test world must forbid a hold somewhere"


def test_stacked_keepouts_equal_the_definition(world):
    """The queries' keep-out test of mixed types in one call (GrownStack) gives the verdict of
    ``_conflict`` (each pair's keep-out, the vectors shrunk by the growth) on random relative
    vectors around every pair's boundary, moving and at rest."""
    problem = world[0]
    occ = Occupancy(problem, [], HORIZON)
    rng = np.random.default_rng(3)
    n_types = 1 + max(max(k) for k in problem.keepouts)
    for ta in range(n_types):
        for rest in (False, True):
            tb = rng.integers(0, n_types, 4000)
            reach = np.array([problem.keepouts[(ta, int(b))].reach_xy_m for b in tb])
            d = np.c_[rng.uniform(-1.2, 1.2, (4000, 2)) * reach[:, None], rng.uniform(-3.0, 3.0, 4000)]
            d[:200, 2] = rng.uniform(-0.02, 0.02, 200)  # within the tube of dz = 0: both directions apply
            got = occ.stack(ta, rest).conflict(d, tb)
            want = np.array(
                [_conflict(problem.keepouts[(ta, int(b))], v[None], rest, SAMPLING_GROWTH_M)[0] for v, b in zip(d, tb)]
            )
            assert 0.1 < want.mean() < 0.9, "the vectors must straddle the boundary"
            np.testing.assert_array_equal(got, want)
