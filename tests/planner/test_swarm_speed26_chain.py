"""Stop 64 round 26A: the safe-interval timing along a chain (``proxplan.planner.swarm.chain``) asks a
waypoint's holds only when the search first needs them, and a move's departures only from the first
to the last departure whose arrival may hold its waypoint. The answer is the same as asking every
departure query over the whole horizon: the same track, move for move, on busy occupancies, straight
or through waypoints."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.planner.swarm.chain import MAX_RUN, MAX_SHORTCUT, STATIC_CHECKS_PER_STEP, _runs, _time_chain
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.tracks import GRID_DT_S
from proxplan.planner.swarm.wave import wave_route
from proxplan.planner.timing import CORNER_DEVIATION_M
from proxplan.planner.timing.profile import LineMove, RunMove, rest_to_rest

from .test_swarm_chain_windows import HORIZON, _busy


class _WholeHorizon:
    """An occupancy answering every departure query over the whole horizon (exact in any window),
    counting the departure steps it was asked about."""

    def __init__(self, occ: Occupancy):
        self._occ = occ
        self.asked = 0

    def __getattr__(self, name):
        return getattr(self._occ, name)

    def forbidden_departures(self, agent, q_m, from_step=0, until_step=None):
        until = self._occ.horizon if until_step is None else until_step
        self.asked += max(0, until - from_step)
        return self._occ.forbidden_departures(agent, q_m, 0, None)


def _same_track(a, b) -> None:
    assert (a is None) == (b is None)
    if a is None:
        return
    assert a.arrival_step == b.arrival_step
    assert [d for d, _ in a.track.moves] == [d for d, _ in b.track.moves]
    np.testing.assert_array_equal(a.track.positions_m, b.track.positions_m)
    np.testing.assert_array_equal(a.track.moving, b.track.moving)


@pytest.mark.parametrize("seed", range(8))
def test_chain_timing_is_the_same_as_with_every_query_over_the_whole_horizon(seed):
    problem, occ = _busy(seed)
    chains = []
    for agent in range(4):  # 1-3: their own tracks are in the occupancy (no obstacle to themselves)
        s, g = problem.starts_m[agent], problem.goals_m[agent]
        chains.append((agent, np.array([s, g])))
        route = wave_route(occ, agent, s, g)
        if route is not None and len(route) > 2:
            chains.append((agent, route))
    found = 0
    for agent, W in chains:
        for through in (False, True):
            for arrive_by in (None, HORIZON // 2):
                whole = _WholeHorizon(occ)
                want = _time_chain(whole, agent, W, arrive_by=arrive_by, through=through, deviation_m=None)  # type: ignore[arg-type]
                got = _time_chain(occ, agent, W, arrive_by=arrive_by, through=through, deviation_m=None)
                _same_track(got, want)
                found += got is not None
    assert found, "some timing must be found"


def _earliest_arrival(occ: Occupancy, agent: int, W: np.ndarray, through: bool, arrive_by: int | None) -> int | None:
    """The earliest arrival at the end of the chain ``W`` held for good, by brute force over every
    grid step (no search, no windows): the steps the vehicle can be resting at each waypoint, from
    the first on (moves only go forward), closed under waiting where holding is clear; the moves
    are the chain's (straight shortcuts of up to MAX_SHORTCUT waypoints and to the end, runs through
    up to MAX_RUN and to the end), each with every departure asked over the whole horizon."""
    problem, T, m = occ.problem, occ.horizon, len(W) - 1
    limits = problem.limits[agent]
    holds = [occ.forbidden_holds(agent, W[k]) for k in range(m + 1)]
    goal_from = _runs(~holds[m])[-1][0] if (~holds[m]).any() and not holds[m][-1] else T
    reach = [np.zeros(T, dtype=bool) for _ in range(m + 1)]
    if holds[0][0]:
        return None
    reach[0][0] = True
    for k in range(m):
        for a, e in _runs(~holds[k]):  # waiting: from the first step reached in a safe interval to its end
            got = np.flatnonzero(reach[k][a:e])
            if got.size:
                reach[k][a + int(got[0]) : e] = True
        moves = [(j, False) for j in range(k + 1, min(m, k + 1 + MAX_SHORTCUT) + 1)] + [(m, False)]
        if through:
            moves += [(j, True) for j in range(k + 2, min(m, k + 1 + MAX_RUN) + 1)] + [(m, True)] * (m >= k + 2)
        for j, run in set(moves):
            if run:
                mv = RunMove(W[k : j + 1], limits, GRID_DT_S, deviation_m=CORNER_DEVIATION_M)
                if not problem.static_free(mv.positions(STATIC_CHECKS_PER_STEP)).all():
                    continue
            else:
                if not problem.segment_free(W[k], W[j]):
                    continue
                mv = LineMove(W[k], W[j], rest_to_rest(float(np.linalg.norm(W[j] - W[k])), limits, GRID_DT_S))
            n = mv.steps
            if n >= T:
                continue
            leave = reach[k][: T - n] & ~occ.forbidden_departures(agent, mv.positions())[: T - n]
            arrive = np.zeros(T, dtype=bool)
            arrive[n:] = leave
            arrive &= ~holds[j]
            if j == m:
                arrive[:goal_from] = False
            reach[j] |= arrive
    found = np.flatnonzero(reach[m])
    if not found.size or (arrive_by is not None and found[0] > arrive_by):
        return None
    return int(found[0])


@pytest.mark.parametrize("seed", range(4))
def test_chain_timing_arrives_at_the_earliest_step_brute_force_finds(seed):
    problem, occ = _busy(seed)
    found = 0
    for agent in range(4):
        s, g = problem.starts_m[agent], problem.goals_m[agent]
        route = wave_route(occ, agent, s, g)
        for W in [np.array([s, g])] + ([route] if route is not None and len(route) > 2 else []):
            for through in (False, True):
                got = _time_chain(occ, agent, W, arrive_by=None, through=through, deviation_m=None)
                want = _earliest_arrival(occ, agent, W, through, None)
                assert (got is None) == (want is None)
                if got is not None:
                    assert got.arrival_step == want
                    assert not occ.conflicting_agents(got.track)
                    found += 1
    assert found, "some timing must be found"
