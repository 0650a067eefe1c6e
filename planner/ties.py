"""Choices among candidates of equal cost, broken the same way on every machine (round 34W, issue 37: "the same
seed gives the same plan"). Used by the swarm layer and by timing (a turn's cosine against the right angle,
:func:`proxplan.planner.timing.corners.passes_moving`); it imports nothing of the planner, so any of its
packages can use it (it was ``planner/swarm/ties.py`` until stop 76).

A cost computed in floating point may differ in its last bits from one machine to another (numpy's SIMD kernels,
a compiled library such as Ruckig, the order of a reduction): two candidates of equal cost on one machine may be
1 ulp apart on another, and a choice by the raw float then parts. Every choice of a best in the swarm layer
compares costs through :func:`tie_key` instead: the cost rounded to a stated resolution, as an integer, then the
candidate's index or name. Rounding cannot remove every split (a cost within an ulp of a rounding boundary still
parts), but it removes the one that matters in practice: candidates of equal cost by symmetry (a circle's
antipodal lines, a grid's equal moves), computed by different sums of the same terms.

The resolutions are far above float64's error on the quantities they round (relative 1e-16, so 1e-15 m on a 10 m
line, 1e-14 s on a 100 s plan) and far below any difference a plan can resolve (the verifier's 1e-6 m, the
swarm layer's 0.025 s time grid).

A bound made in floating point and read by exact comparisons downstream is rounded up to a stated resolution instead
(:func:`rounded_up`), so that it too is one float on every machine (round 37V: the swarm layer's tracking bound).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import linear_sum_assignment

LENGTH_RESOLUTION_M = 1e-9  # lengths compared after rounding to 1 nm (float64 error on a 100 m line: ~1e-14 m)
TIME_RESOLUTION_S = 1e-9  # times compared after rounding to 1 ns (float64 error on a 1000 s plan: ~1e-13 s)
SQUARED_LENGTH_RESOLUTION_M2 = 1e-8  # squared lengths (CAPT's sum), m^2: 100 m lines x 256 vehicles stay below
# 2^53 once divided by it (1e4 m^2 / 1e-8 x 256 = 2.6e14), so an assignment's integer sum is exact in float64

__all__ = [
    "LENGTH_RESOLUTION_M",
    "SQUARED_LENGTH_RESOLUTION_M2",
    "TIME_RESOLUTION_S",
    "canonical_assignment",
    "quantised",
    "rounded_up",
    "shorter",
    "tie_key",
]


def tie_key(value: float, resolution: float) -> int:
    """``value`` rounded to a multiple of ``resolution`` (same unit), as an integer: the key two candidates of equal
    cost on any machine compare equal by (then by their index or name, given after it in a key tuple)."""
    return int(round(float(value) / resolution))


def rounded_up(value: float, resolution: float) -> float:
    """``value`` rounded up to a multiple of ``resolution`` (same unit), as a float: the least multiple not below it.
    The result is an integer times ``resolution``, so two values that differ in their last bits (one machine's float
    path and another's) give the same float unless a multiple lies between them. For a bound made in floating point
    and used by exact comparisons downstream (round 37V: the tracking bound,
    :mod:`proxplan.planner.swarm.tracking_bound`): rounded up, a bound stays a bound, grown by less than
    ``resolution``."""
    k = math.ceil(float(value) / resolution)
    out = k * resolution
    if out < value:  # the division rounded down onto the multiple below
        out = (k + 1) * resolution
    return out


def shorter(a_s: float, b_s: float) -> bool:
    """``a_s`` shorter than ``b_s`` (s) by at least ``TIME_RESOLUTION_S`` after rounding: the test by which a plan
    replaces the plan in hand (equal plans: the one in hand stays, on every machine)."""
    return tie_key(a_s, TIME_RESOLUTION_S) < tie_key(b_s, TIME_RESOLUTION_S)


def quantised(values: np.ndarray, resolution: float) -> np.ndarray:
    """:func:`tie_key` of every element of ``values`` (int64 array, same shape)."""
    return np.rint(np.asarray(values, dtype=float) / resolution).astype(np.int64)


def canonical_assignment(cost: np.ndarray) -> np.ndarray:
    """The column of each row of the least-sum assignment of the square integer ``cost`` matrix, the
    lexicographically smallest (by row, the lowest column) among the assignments of least sum: one answer whatever
    order the rows and columns came in and whatever optimum ``scipy.optimize.linear_sum_assignment`` would pick.

    Round 35A: one ``linear_sum_assignment``, then exact integer work of about its cost. (1) Dual potentials
    ``u`` (rows), ``v`` (columns) of the assignment found, with ``c[i, j] - u[i] - v[j] >= 0`` everywhere and ``== 0``
    on the assignment: ``v`` the shortest distances in the graph of the moves of one row to another column
    (:func:`_residual_potentials`; it has no negative cycle at a least sum, and when it has one, the solver's
    answer was not of least sum and the cycle is applied, exactly, until none is left). Both conditions are
    asserted. (2) Complementary slackness: an assignment has the least sum exactly when it uses only tight pairs
    (``c[i, j] == u[i] + v[j]``) of an optimal dual, and every perfect matching of the tight pairs has the sum
    ``sum(u) + sum(v)``. So the answer is the lexicographically smallest perfect matching of the tight pairs
    (:func:`_lowest_perfect_matching`), which does not depend on the optimum the solver returned (nor on which
    optimal dual: any one's tight pairs hold every optimum, and only optima). Round 34W's definition (row by row
    the lowest column that keeps the least sum) is the same answer; its implementation (up to one assignment
    problem per column) took 16 s on 256 x 256 distinct costs.

    Exact in int64: the costs are first reduced (each row's minimum, then each column's, subtracted: every
    assignment's sum drops by the same amount, so the same optima in the same order) to ``0..R``; potentials are
    then within ``n R`` and reduced costs within ``(2 n + 1) R``; ``R (2 n + 2) < 2^62`` is required (ValueError
    otherwise; the swarm layer's CAPT costs: ``R`` < 3e15 at 256 vehicles, 1.5e18 of 4.6e18)."""
    c = np.asarray(cost)
    if not np.issubdtype(c.dtype, np.integer):
        raise ValueError("canonical_assignment needs integer costs (quantised first)")
    n = c.shape[0]
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    c = c.astype(np.int64)
    c = c - c.min(axis=1, keepdims=True)
    c = c - c.min(axis=0, keepdims=True)
    span = int(c.max())
    if span * (2 * n + 2) >= 2**62:
        raise ValueError(f"canonical_assignment: costs span {span}, too wide for exact int64 potentials at n = {n}")
    rows, cols = linear_sum_assignment(c.astype(float))
    col_of = np.empty(n, dtype=np.int64)
    col_of[rows] = cols
    v, improved = _residual_potentials(c, col_of)
    while v is None:  # the solver's answer was not of least sum (float rounding): one negative cycle applied
        assert improved is not None
        col_of = improved
        v, improved = _residual_potentials(c, col_of)
    u = c[np.arange(n), col_of] - v[col_of]
    reduced = c - u[:, None] - v[None, :]
    assert int(reduced.min()) >= 0, "canonical_assignment: potentials not dual feasible"
    assert not reduced[np.arange(n), col_of].any(), "canonical_assignment: assignment not tight"
    out = _lowest_perfect_matching(reduced == 0, col_of)
    assert not reduced[np.arange(n), out].any()
    return out


def _residual_potentials(c: np.ndarray, col_of: np.ndarray) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Column potentials ``v`` (int64, n) for the assignment ``col_of`` of the integer matrix ``c``: the shortest
    distances, from a source joined to every column at 0, in the graph whose edge ``col_of[i] -> j`` weighs
    ``c[i, j] - c[i, col_of[i]]`` (row ``i`` moved from its column to ``j``). Bellman-Ford, every edge relaxed at once
    per pass (numpy, exact in int64). Returns ``(v, None)``; when a pass ``n`` still relaxes, the assignment is not of
    least sum and ``(None, improved)`` is returned instead: ``col_of`` with one negative cycle of moves applied."""
    n = c.shape[0]
    rows = np.arange(n)
    weight = c - c[rows, col_of][:, None]  # weight[i, j]: edge col_of[i] -> j
    dist = np.zeros(n, dtype=np.int64)
    pred = np.full(n, -1, dtype=np.int64)  # pred[j]: the row whose move last lowered dist[j]
    for _ in range(n + 1):
        through = dist[col_of][:, None] + weight  # (rows, columns)
        best_row = np.argmin(through, axis=0)
        best = through[best_row, np.arange(n)]
        lower = best < dist
        if not lower.any():
            return dist, None
        dist = np.where(lower, best, dist)
        pred = np.where(lower, best_row, pred)
    # a negative cycle: walk back n steps from a column lowered in the last pass to land on the cycle
    j = int(np.flatnonzero(lower)[0])
    for _ in range(n):
        j = int(col_of[pred[j]])
    cycle, k = [], j
    while True:
        i = int(pred[k])
        cycle.append((i, k))  # row i moves to column k
        k = int(col_of[i])
        if k == j:
            break
    improved = col_of.copy()
    for i, k in cycle:
        improved[i] = k
    return None, improved


def _lowest_perfect_matching(tight: np.ndarray, col_of: np.ndarray) -> np.ndarray:
    """The lexicographically smallest perfect matching (by row, the lowest column) of the bipartite graph ``tight``
    (n x n bool, row i may take column j), given one perfect matching ``col_of`` of it. Rows are fixed in order.
    Row ``i`` can take column ``j`` (its current column ``col_of[i]``, or another held by row ``r``) exactly when the
    rows not yet fixed, without ``i``, can still be matched to the columns not yet fixed, without ``j``: when ``r``
    reaches ``col_of[i]`` by an alternating path (a tight edge to a column, that column's row, its tight edge...).
    One breadth-first search backwards from ``col_of[i]`` finds every such ``r`` at once; the lowest tight column of
    ``i`` among theirs and ``col_of[i]`` is fixed, and the matching is re-routed along the path found."""
    n = tight.shape[0]
    col_of = col_of.copy()
    row_of = np.empty(n, dtype=np.int64)
    row_of[col_of] = np.arange(n)
    open_rows = np.ones(n, dtype=bool)  # rows not yet fixed
    open_cols = np.ones(n, dtype=bool)  # their columns
    for i in range(n):
        open_rows[i] = False
        home = int(col_of[i])
        if int(np.argmax(tight[i] & open_cols)) == home:  # no lower column to try (one tight column, often)
            open_cols[home] = False
            continue
        next_col = np.full(n, -1, dtype=np.int64)  # next_col[r]: the column row r moves to, towards home
        seen = ~open_rows  # rows fixed (and i) are never on a path
        frontier = np.zeros(n, dtype=bool)
        frontier[home] = True
        reached_cols = frontier.copy()
        while frontier.any():
            to_frontier = tight[:, frontier] & ~seen[:, None]
            new_rows = np.flatnonzero(to_frontier.any(axis=1))
            if new_rows.size == 0:
                break
            frontier_cols = np.flatnonzero(frontier)
            next_col[new_rows] = frontier_cols[np.argmax(to_frontier[new_rows], axis=1)]
            seen[new_rows] = True
            frontier = np.zeros(n, dtype=bool)
            frontier[col_of[new_rows]] = True
            frontier &= ~reached_cols
            reached_cols |= frontier
        j = int(np.flatnonzero(tight[i] & reached_cols)[0])  # home is tight and reached: never empty
        open_cols[j] = False
        if j != home:
            r = int(row_of[j])
            col_of[i], row_of[j] = j, i
            while True:  # r takes next_col[r], whose row takes its next, ... until home is taken
                k = int(next_col[r])
                displaced = int(row_of[k]) if k != home else -1
                col_of[r], row_of[k] = k, r
                if k == home:
                    break
                r = displaced
    return col_of
