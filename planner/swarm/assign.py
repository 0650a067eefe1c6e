"""Goal assignment for interchangeable vehicles (scenario key ``assign_goals: by_type``).

Within each vehicle type, the goals listed for vehicles of that type are shared out anew. As in
CAPT (Turpin, Michael and Kumar, IJRR 2014) the assignment first minimises the bottleneck - the
largest single-vehicle minimum flight time (jerk-limited rest-to-rest over the straight line,
:func:`proxplan.planner.timing.durations.min_segment_duration_s`) - and among the assignments that
achieve it, the sum of squared straight-line distances, which makes synchronised straight lines
collision-free when starts and goals are far enough apart. The bottleneck is found by bisection
over the sorted costs with a perfect-matching test
(``scipy.sparse.csgraph.maximum_bipartite_matching``), the sum by ``scipy.optimize.linear_sum_assignment``
on the costs with every pair above the bottleneck excluded; both on the costs rounded to a stated resolution,
the lexicographically smallest of the assignments of least sum taken (:mod:`~proxplan.planner.ties`,
round 34W: the same assignment on every machine and in any order of the vehicles). The assignment's lower bound (no plan
can finish earlier) is the largest single-vehicle minimum time under it.

Where a straight line would pass through an obstacle, its cost is the larger of that time and a certified
bound on the time round the obstacle (``floor_s``, :mod:`~proxplan.planner.swarm.obstacle_costs`; round
24S): the bound stays a lower bound, and an assignment avoids sending a vehicle the long way round where
another as short exists.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import maximum_bipartite_matching

from proxplan.physics import KinematicLimits
from proxplan.planner.ties import (
    LENGTH_RESOLUTION_M,
    SQUARED_LENGTH_RESOLUTION_M2,
    TIME_RESOLUTION_S,
    canonical_assignment,
    quantised,
)
from proxplan.planner.timing.durations import duration_table


@dataclass(frozen=True)
class Assignment:
    goal_of: np.ndarray  # (A,) index of the goal (in the input order) each vehicle takes
    lower_bound_s: float  # largest single-vehicle minimum flight time under the assignment, s


def _min_times(starts: np.ndarray, goals: np.ndarray, limits: KinematicLimits) -> np.ndarray:
    """(n, n) straight-line rest-to-rest minimum time from each start to each goal, s. The table is a step
    function of the distance (its next node up), so each distance is first rounded to ``LENGTH_RESOLUTION_M``
    (planner.ties): a line of 1 m on a node, 1 ulp longer on another machine, would take the next node's time."""
    d = (
        quantised(np.linalg.norm(starts[:, None, :] - goals[None, :, :], axis=2), LENGTH_RESOLUTION_M)
        * LENGTH_RESOLUTION_M
    )
    table = duration_table(limits)
    return np.vectorize(table.duration_s, otypes=[float])(d)


def _bottleneck(cost: np.ndarray) -> int:
    """Smallest threshold c such that a perfect matching uses only pairs of cost <= c (integer costs, exact)."""
    values = np.unique(cost)
    lo, hi = 0, values.size - 1
    n = cost.shape[0]
    while lo < hi:
        mid = (lo + hi) // 2
        graph = csr_matrix(cost <= values[mid])
        match = maximum_bipartite_matching(graph, perm_type="column")
        if int(np.count_nonzero(match >= 0)) == n:
            hi = mid
        else:
            lo = mid + 1
    return int(values[lo])


def assign_group(
    starts_m: np.ndarray, goals_m: np.ndarray, limits: KinematicLimits, floor_s: np.ndarray | None = None
) -> tuple[np.ndarray, float]:
    """Bottleneck-then-sum-of-squares assignment of one type's vehicles (starts (n, 3), m) to its
    goals (n, 3): (goal index per vehicle, bottleneck time s). ``floor_s`` (n, n), s: a lower bound on
    each start-goal pair's time round the obstacles (:func:`~proxplan.planner.swarm.obstacle_costs.pair_bounds_s`);
    a pair's cost is the larger of it and the straight line's time."""
    starts = np.asarray(starts_m, dtype=float)
    goals = np.asarray(goals_m, dtype=float)
    if len(starts) == 0:
        return np.zeros(0, dtype=np.int64), 0.0
    times = _min_times(starts, goals, limits)
    if floor_s is not None:
        times = np.maximum(times, floor_s)
    # costs compared as integers at a stated resolution (planner.ties): equal costs on one machine are equal on
    # every machine, and among assignments of equal cost the lexicographically smallest is taken (round 34W)
    steps = quantised(times, TIME_RESOLUTION_S)
    bottleneck = _bottleneck(steps)
    sq = quantised(np.sum((starts[:, None, :] - goals[None, :, :]) ** 2, axis=2), SQUARED_LENGTH_RESOLUTION_M2)
    big = int(sq.max()) * len(starts) * 10 + 1
    goal_of = canonical_assignment(np.where(steps <= bottleneck, sq, big))
    return goal_of, float(times[np.arange(len(starts)), goal_of].max())


def assign_by_type(
    starts_m: np.ndarray,
    goals_m: np.ndarray,
    type_names: list[str],
    limits: list[KinematicLimits],
    floor_s: np.ndarray | None = None,
) -> Assignment:
    """The assignment of every vehicle (starts (A, 3), m; the goals listed for them (A, 3), m;
    their type names and limits) to a goal of its own type (see module); ``floor_s`` (A, A), s: as
    :func:`assign_group`'s, vehicle i's start to the goal listed for vehicle g."""
    starts = np.asarray(starts_m, dtype=float)
    goals = np.asarray(goals_m, dtype=float)
    goal_of = np.arange(len(starts))
    lb = 0.0
    for t in sorted(set(type_names)):
        members = np.array([i for i, n in enumerate(type_names) if n == t], dtype=np.int64)
        floor = None if floor_s is None else np.asarray(floor_s, dtype=float)[np.ix_(members, members)]
        g, b = assign_group(starts[members], goals[members], limits[int(members[0])], floor)
        goal_of[members] = members[g]
        lb = max(lb, b)
    return Assignment(goal_of, lb)
