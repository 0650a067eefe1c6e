"""Goal assignment of interchangeable vehicles (proxplan.planner.swarm.assign): the bottleneck, then
the least sum of squared distances, equal to enumerating every permutation."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from proxplan.physics import KinematicLimits
from proxplan.planner.swarm import assign_group
from proxplan.planner.timing import min_segment_duration_s


def test_assignment_equals_the_brute_force_optimum_on_six_vehicles():
    """Bottleneck time first, then the least sum of squared distances: the same as enumerating
    every permutation."""
    rng = np.random.default_rng(3)
    lim = KinematicLimits(1.5, 3.0, 12.0)
    for _ in range(5):
        starts = np.column_stack([rng.uniform(-3, 3, 6), rng.uniform(-3, 3, 6), np.full(6, 1.0)])
        goals = np.column_stack([rng.uniform(-3, 3, 6), rng.uniform(-3, 3, 6), np.full(6, 1.5)])
        goal_of, bottleneck = assign_group(starts, goals, lim)

        def cost(perm, starts=starts, goals=goals):
            t = max(min_segment_duration_s(float(np.linalg.norm(starts[i] - goals[perm[i]])), lim) for i in range(6))
            sq = sum(float(np.sum((starts[i] - goals[perm[i]]) ** 2)) for i in range(6))
            return t, sq

        best = min(itertools.permutations(range(6)), key=lambda p: cost(p))
        assert sorted(goal_of.tolist()) == list(range(6))
        assert cost(tuple(goal_of)) == pytest.approx(cost(best))
        assert bottleneck == pytest.approx(cost(best)[0])
