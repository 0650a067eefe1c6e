"""Safe-interval timing along a chain (proxplan.planner.swarm.chain): a move to the end asks its
departures in growing windows and stops at the first free one; the answer is the same whatever the
first window (one step, or the whole horizon at once), conflict-free, and for a straight line the
first departure that the others allow and that arrives in the end's last safe interval."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.planfile import scenario_from_dict
from proxplan.planner.formations import grid_reshuffle
from proxplan.planner.swarm import swarm_problem
from proxplan.planner.swarm.chain import _runs, _time_chain
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.tracks import GRID_DT_S, GridTrack
from proxplan.planner.swarm.wave import wave_route
from proxplan.planner.timing.profile import LineMove, rest_to_rest

HORIZON = 900  # steps (22.5 s): every departure below leaves and arrives well within it


def _busy(seed: int):
    """A 16-vehicle reshuffle with every vehicle but 0 on its straight line, leaving at a random step
    (0-6 s), so that vehicle 0 has others crossing its way and parked at their goals."""
    problem = swarm_problem(scenario_from_dict(grid_reshuffle(16, seed=seed), label="test scenario"))
    rng = np.random.default_rng(seed)
    tracks = []
    for b in range(1, problem.n_agents):
        s, g = problem.starts_m[b], problem.goals_m[b]
        move = LineMove(s, g, rest_to_rest(float(np.linalg.norm(g - s)), problem.limits[b], GRID_DT_S))
        tracks.append(GridTrack(b, int(problem.type_index[b]), s.copy(), [(int(rng.integers(0, 240)), move)]))
    return problem, Occupancy(problem, tracks, HORIZON)


def _same(a, b) -> bool:
    if a is None or b is None:
        return a is None and b is None
    return a.arrival_step == b.arrival_step and np.array_equal(a.track.positions_m, b.track.positions_m)


@pytest.mark.parametrize("seed", range(6))
def test_the_timing_does_not_depend_on_the_first_window_and_is_conflict_free(seed):
    problem, occ = _busy(seed)
    s, g = problem.starts_m[0], problem.goals_m[0]
    chains = [np.array([s, g])]
    route = wave_route(occ, 0, s, g)
    if route is not None and len(route) > 2:
        chains.append(route)
    for W in chains:
        for through in (False, True):
            got = [
                _time_chain(occ, 0, W, arrive_by=None, through=through, deviation_m=None, end_window_steps=w)
                for w in (1, 7, 64, HORIZON)
            ]
            assert all(_same(got[0], x) for x in got[1:])
            if got[0] is not None:
                assert not occ.conflicting_agents(got[0].track)


@pytest.mark.parametrize("seed", range(6))
def test_a_straight_line_leaves_at_the_first_departure_that_reaches_the_end_for_good(seed):
    """The straight line from start to goal (one move, rest to rest): its departure is the first that
    the others allow, within the start's first safe interval, whose arrival falls in the goal's last
    safe interval (the one that lasts to the horizon), asked over the whole horizon at once."""
    problem, occ = _busy(seed)
    s, g = problem.starts_m[0], problem.goals_m[0]
    move = LineMove(s, g, rest_to_rest(float(np.linalg.norm(g - s)), problem.limits[0], GRID_DT_S))
    n = move.steps
    bad = occ.forbidden_departures(0, move.positions())
    start_until = _runs(~occ.forbidden_holds(0, s))[0][1]
    goal_runs = _runs(~occ.forbidden_holds(0, g))
    goal_from = goal_runs[-1][0] if goal_runs and goal_runs[-1][1] >= HORIZON else None
    expected = None
    if goal_from is not None and not occ.forbidden_holds(0, s)[0]:
        ok = [d for d in range(max(0, goal_from - n), min(start_until, HORIZON - n)) if not bad[d]]
        expected = ok[0] + n if ok else None
    got = _time_chain(occ, 0, np.array([s, g]), arrive_by=None, through=False, deviation_m=None)
    assert (got is None) == (expected is None)
    if got is not None:
        assert got.arrival_step == expected
