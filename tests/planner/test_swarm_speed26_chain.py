"""Stop 64 round 26A: the safe-interval timing along a chain (``proxplan.planner.swarm.chain``) asks a
waypoint's holds only when the search first needs them, and a move's departures only from the first
to the last departure whose arrival may hold its waypoint. The answer is the same as asking every
departure query over the whole horizon: the same track, move for move, on busy occupancies, straight
or through waypoints."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.planner.swarm.chain import _time_chain
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.wave import wave_route

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
