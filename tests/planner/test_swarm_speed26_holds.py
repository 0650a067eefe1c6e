"""Stop 64 round 26A: ``Occupancy.forbidden_holds`` keeps its answer for an agent whose own track is in
the occupancy too (keyed by that agent: its own track is left out of its answer), so a vehicle
re-timed or repaired in place asks each of its points once per state of the tracks. The kept answer
is the one asked afresh, for that agent, for another agent at the same point, and after a change."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.planner.swarm.occupancy import Occupancy

from .test_swarm_chain_windows import HORIZON, _busy


@pytest.mark.parametrize("seed", range(4))
def test_kept_holds_are_the_answers_asked_afresh(seed):
    problem, occ = _busy(seed)
    rng = np.random.default_rng(seed)
    points = [problem.starts_m[a] for a in range(4)] + [problem.goals_m[a] for a in range(4)]
    points += [p + np.r_[rng.uniform(-0.3, 0.3, 2), 0.0] for p in points[:4]]
    differ = 0
    for w in points:
        for agent in (1, 2, 0):  # 1 and 2: their tracks are in the occupancy; 0: not
            first = occ.forbidden_holds(agent, w)
            again = occ.forbidden_holds(agent, w.copy())
            assert again is first, "asked again in the same state: the kept answer"
            fresh = Occupancy(problem, list(occ.tracks.values()), HORIZON)._forbidden_holds(
                agent, int(problem.type_index[agent]), np.ascontiguousarray(w, dtype=float)
            )
            np.testing.assert_array_equal(first, fresh)
        differ += not np.array_equal(occ.forbidden_holds(1, w), occ.forbidden_holds(2, w))
    assert differ, "agents left out of their own answers: some answers must differ"
    # a change of the tracks drops what was kept
    moved = occ.tracks[1]
    occ.remove(1)
    for w in points:
        np.testing.assert_array_equal(
            occ.forbidden_holds(2, w),
            Occupancy(problem, list(occ.tracks.values()), HORIZON)._forbidden_holds(
                2, int(problem.type_index[2]), np.ascontiguousarray(w, dtype=float)
            ),
        )
    occ.put(moved)
    np.testing.assert_array_equal(
        occ.forbidden_holds(2, points[0]),
        Occupancy(problem, list(occ.tracks.values()), HORIZON)._forbidden_holds(
            2, int(problem.type_index[2]), np.ascontiguousarray(points[0], dtype=float)
        ),
    )
