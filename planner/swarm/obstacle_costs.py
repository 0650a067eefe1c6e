"""Certified times round the obstacles for every start-goal pair of interchangeable vehicles (issue 37
item 5, round 24S): the costs of the goal assignment (:mod:`proxplan.planner.swarm.assign`) where a straight
line would pass through an obstacle.

For a start on one side of an obstacle's extent along x or y and a goal on the other, every route crosses
both planes bounding that extent; :func:`proxplan.planner.bounds.window_time_s` proves that the time of any
such flight is at least the reach time from rest of the start to the nearer plane's free window, plus the
extent's thickness at full speed, plus the reach time from the farther plane's window to the goal at rest
(:func:`proxplan.planner.bounds.reach_through_s`, here from :func:`proxplan.planner.bounds.window_gaps_m`). The same bound per pair, the largest over the obstacles'
extents crossed, is a lower bound on that vehicle's time to that goal: so the bottleneck over these costs
is still a bound no plan of the assignment's problem can beat, and where the straight lines of the
assignment went through an obstacle it now weighs the way round (corridor-64 by type: two lines through
the wall, the slower flown alone round it 1.84 B; measured by ``benchmarks/why_by_type.py``).
The distances timed depend on the start or the goal alone, so each is computed once per window, for all
vehicles at once (n per window, not n squared), and timed with each row's limits in one array.
"""

from __future__ import annotations

import math

import numpy as np

from proxplan.planfile import Scenario
from proxplan.planner.bounds import Window, rest_to_free_time_s, slabs, window, window_gaps_m

__all__ = ["pair_bounds_s"]


def pair_bounds_s(scenario: Scenario, names: list[str]) -> np.ndarray:
    """(A, A) s: for vehicle ``names[i]``'s start and the goal listed for ``names[g]``, the largest
    certified time over the obstacles' extents the pair lies across (0 where it lies across none; see
    module), with vehicle i's limits and body radius."""
    tasks = [scenario.vehicles[n] for n in names]
    starts = np.array([t.start_m for t in tasks], dtype=float)
    goals = np.array([t.goal_m for t in tasks], dtype=float)
    out = np.zeros((len(names), len(names)))
    windows: dict[tuple[int, float, float], Window] = {}
    gaps: dict[tuple[str, tuple[int, float, float]], np.ndarray] = {}  # (start/goal, window) -> (A,) m

    def win(axis: int, coord: float, rb: float) -> tuple[int, float, float]:
        key = (axis, round(coord, 9), round(rb, 9))
        if key not in windows:
            windows[key] = window(scenario, axis, coord, rb)
        return key

    def gap_m(end: str, key: tuple[int, float, float]) -> np.ndarray:
        """The distances every start (or goal) is timed over to that window (:func:`window_gaps_m`),
        computed once per window for all vehicles (round 30B: point by point, 1.2 s of pillar-64's CPU)."""
        if (end, key) not in gaps:
            gaps[(end, key)] = window_gaps_m(starts if end == "start" else goals, windows[key])
        return gaps[(end, key)]

    for slab in slabs(scenario):
        k = slab.axis
        below_s, above_s = starts[:, k] < slab.lo_m, starts[:, k] > slab.hi_m
        below_g, above_g = goals[:, k] < slab.lo_m, goals[:, k] > slab.hi_m
        across = (below_s[:, None] & above_g[None, :]) | (above_s[:, None] & below_g[None, :])
        if not across.any():
            continue
        for i in np.flatnonzero(across.any(axis=1)):
            lim, rb = tasks[i].kinematic_limits, tasks[i].body_radius_m
            near, far = (slab.lo_m, slab.hi_m) if below_s[i] else (slab.hi_m, slab.lo_m)
            k_near, k_far = win(k, near, rb), win(k, far, rb)
            leave = _reach_s(gap_m("start", k_near)[i], windows[k_near], lim)
            inside = (slab.hi_m - slab.lo_m) / lim.max_speed_mps
            cols = np.flatnonzero(across[i])
            # each goal's reach with vehicle i's limits (goals of another type too: the matrix is A x A)
            arrive = _reach_s(gap_m("goal", k_far)[cols], windows[k_far], lim)
            out[i, cols] = np.maximum(out[i, cols], leave + inside + arrive)
    return out


def _reach_s(gap_m, win: Window, limits):
    """:func:`~proxplan.planner.bounds.reach_through_s` from the distances ``gap_m`` (m, scalar or array) to
    the window ``win``: inf where it has no free cell."""
    if win.centres_m.shape[0] == 0:
        return np.full(np.shape(gap_m), np.inf) if np.ndim(gap_m) else math.inf
    return rest_to_free_time_s(gap_m, limits)
