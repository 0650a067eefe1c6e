"""The guard's memo of sub-plan verdicts (round 25A, proxplan.planner.swarm.verify_guard): a sub-plan asked
again is answered as the verifier answered it, and the key tells apart what the verdict depends on."""

import pickle

import numpy as np
import pytest

from proxplan.planner.swarm.problem import swarm_problem
from proxplan.planner.swarm.tracks import GridTrack
from proxplan.planner.swarm.verify_guard import VerifyGuard, _sub_plan_key

from .test_swarm_repair_sum import FAR_Y_M, _scenario, _tracks, line_case


@pytest.mark.parametrize("line_y_m", [0.0, FAR_Y_M])
def test_a_sub_plan_asked_again_is_answered_as_the_first_time(line_y_m: float) -> None:
    """Under the high Crazyflie the line fails, far aside it passes (test_swarm_repair_sum): asked twice,
    and once more with the same tracks rebuilt (equal, other objects), the guard answers as the verifier
    each time, building the sub-plan once."""
    sc, problem, tracks, mid, whole = line_case(line_y_m)
    guard = VerifyGuard(sc, problem, problem, ())
    assert guard.around(tracks, {mid: None}) == whole
    assert guard.around(tracks, {mid: None}) == whole
    rebuilt = pickle.loads(pickle.dumps(tracks))
    assert rebuilt[mid] is not tracks[mid]
    assert guard.around(rebuilt, {mid: None}) == whole
    assert (guard.local, guard.recalled, guard.local_failed) == (3, 2, 0 if whole else 3)
    assert whole == (line_y_m == FAR_Y_M)  # the case is what it says


def test_the_key_tells_apart_tracks_steps_and_loops() -> None:
    sc = _scenario(0.0)
    problem = swarm_problem(sc)
    tracks = _tracks(sc, problem)
    mid = problem.names.index("mid")
    keep = sorted(tracks)
    key = _sub_plan_key(keep, tracks, 100, [mid])
    assert key == _sub_plan_key(keep, pickle.loads(pickle.dumps(tracks)), 100, [mid])
    assert key != _sub_plan_key(keep, tracks, 101, [mid])
    assert key != _sub_plan_key(keep, tracks, 100, keep)
    assert key != _sub_plan_key([a for a in keep if a != mid], tracks, 100, [mid])  # the agents of the sub-plan
    old = tracks[mid]
    late = GridTrack(mid, old.type, old.start_m, [(k0 + 1, mv) for k0, mv in old.moves])  # one step later
    assert key != _sub_plan_key(keep, {**tracks, mid: late}, 100, [mid])
    aside = _tracks(_scenario(FAR_Y_M), problem)[mid]
    assert not np.array_equal(aside.start_m, old.start_m)
    assert key != _sub_plan_key(keep, {**tracks, mid: aside}, 100, [mid])
