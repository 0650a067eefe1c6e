"""The departure query's index (proxplan.planner.swarm.departures): on randomised occupancies it
answers exactly what a step-by-step check of every other track gives, inside the asked window
(and nothing outside it), and a run of single-vehicle plannings gives the same tracks whether the
chain asks the index or a check of every segment against every move sample."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from proxplan.planfile import scenario_from_dict
from proxplan.planner.formations import corridor, grid_reshuffle
from proxplan.planner.swarm.departures import BUCKET_STEPS, DepartureIndex
from proxplan.planner.swarm.occupancy import SAMPLING_GROWTH_M, Occupancy, _conflict
from proxplan.planner.swarm.priority import plan_one, predicted_track
from proxplan.planner.swarm.priority_order import dependency_order
from proxplan.planner.swarm.problem import swarm_problem
from proxplan.planner.swarm.tracks import GRID_DT_S, GridTrack
from proxplan.planner.timing import CORNER_DEVIATION_M
from proxplan.planner.timing.profile import LineMove, RunMove, rest_to_rest

HORIZON = 4 * BUCKET_STEPS  # 4 time buckets: segments in one, rests and parked ends over several


@pytest.fixture(scope="module")
def problem():
    return swarm_problem(scenario_from_dict(grid_reshuffle(9, seed=4), label="test"))


def _line(problem, a, p0, p1) -> LineMove:
    return LineMove(p0, p1, rest_to_rest(float(np.linalg.norm(p1 - p0)), problem.limits[a], GRID_DT_S))


def _random_track(problem, a: int, rng, centre: np.ndarray) -> GridTrack:
    """A track of agent ``a`` crossing near ``centre``: one to three moves (lines or flights
    through a waypoint) with random rests between, then parked away from it, or vanishing; or a
    place held for good, or a prediction."""
    kind = rng.integers(0, 6)
    s = problem.starts_m[a]
    ty = int(problem.type_index[a])

    def away() -> np.ndarray:  # a place 1.5-2.5 m from the centre (parking on the queried moves blocks all)
        phi = rng.uniform(0.0, 2.0 * np.pi)
        return (
            centre + np.r_[rng.uniform(1.5, 2.5) * np.array([np.cos(phi), np.sin(phi)]), rng.choice([-0.5, 0.0, 0.5])]
        )

    if kind == 0:  # rests at a place for good
        return GridTrack(a, ty, away(), [])
    if kind == 1:
        return predicted_track(problem, a, hold_s=float(rng.uniform(0.0, 3.0)))
    moves, t, cur = [], int(rng.integers(0, 60)), s.copy()
    n = int(rng.integers(1, 4))
    for i in range(n):
        nxt = centre + np.r_[rng.uniform(-1.2, 1.2, 2), rng.choice([-0.5, 0.0, 0.5])] if i < n - 1 else away()
        if rng.random() < 0.5:
            mid = 0.5 * (cur + nxt) + np.r_[rng.uniform(-0.4, 0.4, 2), 0.0]
            mv = RunMove(np.array([cur, mid, nxt]), problem.limits[a], GRID_DT_S, deviation_m=CORNER_DEVIATION_M)
        else:
            mv = _line(problem, a, cur, nxt)
        moves.append((t, mv))
        t += mv.steps + int(rng.integers(0, 3 * BUCKET_STEPS // 2))  # rests within a bucket and over several
        cur = nxt
    tr = GridTrack(a, ty, s.copy(), moves)
    return tr.vanishing(tr.arrival_step + 1) if kind == 2 else tr


def _brute_force(problem, tracks, me: int, q: np.ndarray) -> np.ndarray:
    """(HORIZON,) forbidden departures by the definition: every departure step, every move sample,
    every other track present at that step (its sample, its parked end, nothing once vanished)."""
    ta = int(problem.type_index[me])
    K = q.shape[0]
    steps = np.arange(HORIZON)[:, None] + np.arange(K)[None, :]  # (d, k) -> step
    out = np.zeros(HORIZON, dtype=bool)
    for tr in tracks:
        if tr.agent == me:
            continue
        present = steps <= tr.arrival_step if tr.vanishes else np.ones(steps.shape, dtype=bool)
        d = tr.position_at_steps(steps.reshape(-1)) - np.tile(q, (HORIZON, 1))
        hit = _conflict(problem.keepouts[(ta, tr.type)], d, False, SAMPLING_GROWTH_M).reshape(steps.shape)
        out |= (hit & present).any(axis=1)
    return out


@pytest.mark.parametrize("seed", range(6))
def test_departures_equal_the_definition_on_random_occupancies(problem, seed):
    rng = np.random.default_rng(seed)
    me = int(rng.integers(0, problem.n_agents))
    centre = 0.5 * (problem.starts_m[me] + problem.goals_m[me])
    tracks = [_random_track(problem, a, rng, centre) for a in range(problem.n_agents) if a != me]
    if seed % 2:  # the queried vehicle's own track in the occupancy: no obstacle to itself
        tracks.append(_random_track(problem, me, rng, centre))
    occ = Occupancy(problem, tracks, HORIZON)
    s, g = problem.starts_m[me], problem.goals_m[me]
    via = centre + np.r_[rng.uniform(-0.6, 0.6, 2), 0.0]
    lim = problem.limits[me]
    index = occ._departure_index()
    for q, straight in (
        (_line(problem, me, s, g).positions(), True),
        (RunMove(np.array([s, via, g]), lim, GRID_DT_S, deviation_m=CORNER_DEVIATION_M).positions(), False),
        (_line(problem, me, via, via + np.r_[0.3, -0.2, 0.0]).positions(), True),  # short, inside the crowd
    ):
        # a straight move is asked without the trees (DepartureIndex.line_pairs); the run is when it
        # goes forward along its chord (the reach widened by its distance from it), else by the trees
        if straight:
            assert index.line_pairs(q, problem.reach_xy_m, 0, HORIZON) is not None
        want = _brute_force(problem, tracks, me, q)
        assert want.any() and not want.all(), "the random world must constrain the move somewhere"
        np.testing.assert_array_equal(occ.forbidden_departures(me, q), want)
        for _ in range(8):
            lo = int(rng.integers(0, HORIZON))
            hi = int(rng.integers(lo, HORIZON + 20))
            got = occ.forbidden_departures(me, q, from_step=lo, until_step=hi)
            np.testing.assert_array_equal(got[lo:hi], want[lo:hi])
            assert not got[:lo].any() and not got[hi:].any(), "nothing is forbidden outside the window"


def test_line_pairs_leave_out_what_is_not_a_line(problem):
    """A vertical move and a line flown back over itself do not go forward along the line from
    their first to their last sample: the trees answer them (line_pairs gives None)."""
    occ = Occupancy(problem, [predicted_track(problem, a, hold_s=1.0) for a in range(problem.n_agents)], HORIZON)
    index: DepartureIndex = occ._departure_index()
    a = 0
    p = problem.starts_m[a]
    up = _line(problem, a, p, p + np.r_[0.0, 0.0, 0.5]).positions()
    there = _line(problem, a, p, p + np.r_[1.0, 0.0, 0.0]).positions()
    back = np.r_[there, there[::-1]]
    for q in (up, back):
        assert index.line_pairs(q, problem.reach_xy_m, 0, HORIZON) is None
        assert (
            index.pairs(q, problem.reach_xy_m, 0, HORIZON)[0].size
            == index.tree_pairs(q, problem.reach_xy_m, 0, HORIZON)[0].size
        )
    assert index.line_pairs(there, problem.reach_xy_m, 0, HORIZON) is not None


class _EverySegment(Occupancy):
    """The departure query by every segment of every other track against every move sample (no
    index, no reach, no window pruning; the same segments), checked against the index's answer
    at each call."""

    calls = 0

    def forbidden_departures(self, agent, q_m, from_step=0, until_step=None):
        fast = super().forbidden_departures(agent, q_m, from_step, until_step)
        T = self.horizon
        until = T if until_step is None else min(T, max(int(until_step), from_step))
        q = np.asarray(q_m, dtype=float)
        ta = int(self.problem.type_index[agent])
        out = np.zeros(T, dtype=bool)
        for b, tr in self.tracks.items():
            if b == agent:
                continue
            P, t0, t1, _ = self._segments.get(b, (np.zeros((0, 3)), np.zeros(0, int), np.zeros(0, int), None))
            if not tr.vanishes:  # parked for good after its last sample
                P, t0, t1 = np.r_[P, tr.end_m[None]], np.r_[t0, tr.arrival_step], np.r_[t1, 10**9]
            k = np.arange(q.shape[0])
            hit = self.stack(ta, False).conflict(
                (P[:, None] - q[None]).reshape(-1, 3), np.full(P.shape[0] * k.size, tr.type)
            )
            r, kk = np.nonzero(hit.reshape(P.shape[0], k.size))
            for lo, hi in zip(np.maximum(t0[r] - kk, from_step), np.minimum(t1[r] - kk, until)):
                if hi > lo:
                    out[lo:hi] = True
        np.testing.assert_array_equal(fast[from_step:until], out[from_step:until])
        type(self).calls += 1
        return out


@pytest.mark.parametrize("layout", ["corridor", "grid"])
def test_plannings_give_the_same_tracks_with_every_segment_checked(layout):
    """Single-vehicle plannings in dependency order (vehicles not planned yet predicted, as in
    prioritised planning) on a 10-vehicle layout: the same tracks with the index as with every
    segment checked, and both answers equal at every query."""
    doc = corridor(10) if layout == "corridor" else grid_reshuffle(10, seed=2)
    problem = swarm_problem(scenario_from_dict(doc, label="test"))
    horizon = 600
    runs = []
    for cls in (Occupancy, _EverySegment):
        problem = replace(problem)  # an empty memo (swarm.memo): every search asks this occupancy
        occ = cls(problem, [predicted_track(problem, a, hold_s=1.0) for a in range(problem.n_agents)], horizon)
        out = []
        for a in dependency_order(problem):
            occ.remove(a)
            tr = plan_one(occ, a, through=False)
            assert tr is not None, f"{problem.names[a]} must be plannable here"
            occ.put(tr)
            out.append(tr)
        runs.append(out)
    assert _EverySegment.calls > 50, "the plannings must ask the departure query"
    assert any(tr.route_m is not None and len(tr.route_m) > 2 for tr in runs[0]), "some vehicle must route round"
    for fast, slow in zip(*runs):
        np.testing.assert_array_equal(fast.positions_m, slow.positions_m)
