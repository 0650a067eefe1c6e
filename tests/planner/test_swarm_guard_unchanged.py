"""The check around a change that moves no track (by more than ``verify_guard.MOVED_M``) answers as the whole
plan's check (it raised an IndexError on the empty set of differing steps, found by round 24B with every order
set to "far goals first" on circle-64)."""

from dataclasses import replace

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


@pytest.mark.parametrize("line_y_m", [0.0, FAR_Y_M])
@pytest.mark.parametrize("left_out", ["low", "high"])
def test_a_change_that_moves_nothing_with_a_vehicle_left_out_is_judged_on_the_tracks_in_place(
    line_y_m: float, left_out: str
) -> None:
    """The makespan repair asks about a track planned again while members of its neighbourhood not
    planned yet are left out (not flying): where that track is its old one to MOVED_M, the whole
    plan's check is of the tracks in place (round 32A: it looked the left-out agents up and raised a
    KeyError on corridor-12 with the raised arm)."""
    sc = _scenario(line_y_m)
    problem = swarm_problem(sc)
    tracks = _tracks(sc, problem)
    mid, gone = problem.names.index("mid"), problem.names.index(left_out)
    in_place = {a: t for a, t in tracks.items() if a != gone}
    again = replace(tracks[mid])  # planned again: the same track, another object
    guard = VerifyGuard(sc, problem, problem, ())
    without = replace(sc, vehicles={n: v for n, v in sc.vehicles.items() if n != left_out})
    assert guard.around({**in_place, mid: again}, {mid: tracks[mid]}) == _verifies(without, problem, in_place)
    assert guard.whole == 1 and guard.local == 0
