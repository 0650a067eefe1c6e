"""The check around a change that moves no track (by more than ``verify_guard.MOVED_M``) answers as the whole
plan's check (it raised an IndexError on the empty set of differing steps, found by round 24B with every order
set to "far goals first" on circle-64)."""

import pytest

from proxplan.planner.swarm.problem import swarm_problem
from proxplan.planner.swarm.verify_guard import VerifyGuard

from .test_swarm_repair_sum import FAR_Y_M, _scenario, _tracks, _verifies


@pytest.mark.parametrize("line_y_m", [0.0, FAR_Y_M])
def test_a_change_that_moves_nothing_is_judged_on_the_whole_plan(line_y_m: float) -> None:
    sc = _scenario(line_y_m)
    problem = swarm_problem(sc)
    tracks = _tracks(sc, problem)
    mid = problem.names.index("mid")
    guard = VerifyGuard(sc, problem, problem, ())
    assert guard.around(tracks, {mid: tracks[mid]}) == _verifies(sc, problem, tracks)
    assert guard.whole == 1 and guard.local == 0  # the whole plan's check answered, no sub-plan was built
