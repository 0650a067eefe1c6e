"""Choices among candidates of equal cost, broken the same way on every machine (round 34W, issue 37: "the same
seed gives the same plan").

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
    "shorter",
    "tie_key",
]


def tie_key(value: float, resolution: float) -> int:
    """``value`` rounded to a multiple of ``resolution`` (same unit), as an integer: the key two candidates of equal
    cost on any machine compare equal by (then by their index or name, given after it in a key tuple)."""
    return int(round(float(value) / resolution))


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
    Integer costs (:func:`quantised`) make the sums exact. Row by row, the lowest column that still allows the least
    sum is fixed: at most one assignment problem per column below the column of an optimum found."""
    c = np.asarray(cost)
    if not np.issubdtype(c.dtype, np.integer):
        raise ValueError("canonical_assignment needs integer costs (quantised first)")
    n = c.shape[0]
    cf = c.astype(float)

    def least(rows: np.ndarray, cols: np.ndarray) -> tuple[float, np.ndarray]:
        if rows.size == 0:
            return 0.0, np.zeros(0, dtype=np.int64)
        sub = cf[np.ix_(rows, cols)]
        r, k = linear_sum_assignment(sub)
        out = np.empty(rows.size, dtype=np.int64)
        out[r] = cols[k]
        return float(sub[r, k].sum()), out

    out = np.empty(n, dtype=np.int64)
    free = np.arange(n)
    total, current = least(np.arange(n), free)
    for i in range(n):
        rest_rows = np.arange(i + 1, n)
        chosen = int(current[0])
        for j in free[free < chosen]:  # a lower column with the same least sum wins
            others = free[free != j]
            if rest_rows.size and cf[i, j] + cf[np.ix_(rest_rows, others)].min(axis=1).sum() > total + 0.5:
                continue  # not even each remaining row's cheapest column reaches the least sum
            s, sol = least(rest_rows, others)
            if math.isclose(cf[i, j] + s, total, rel_tol=0.0, abs_tol=0.5):  # integer sums: equal or >= 1 apart
                chosen, current = int(j), np.concatenate([[j], sol])
                break
        out[i] = chosen
        total -= cf[i, chosen]
        free = free[free != chosen]
        current = current[1:]
    return out
