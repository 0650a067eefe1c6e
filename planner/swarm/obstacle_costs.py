"""Certified times round the obstacles for every start-goal pair of interchangeable vehicles (issue 37
item 5, round 24S): the costs of the goal assignment (:mod:`proxplan.planner.swarm.assign`) where a straight
line would pass through an obstacle.

For a start on one side of an obstacle's extent along x or y and a goal on the other, every route crosses
both planes bounding that extent; :func:`proxplan.planner.bounds.window_time_s` proves that the time of any
such flight is at least the reach time from rest of the start to the nearer plane's free window, plus the
extent's thickness at full speed, plus the reach time from the farther plane's window to the goal at rest
(:func:`proxplan.planner.bounds.reach_through_s`). The same bound per pair, the largest over the obstacles'
extents crossed, is a lower bound on that vehicle's time to that goal: so the bottleneck over these costs
is still a bound no plan of the assignment's problem can beat, and where the straight lines of the
assignment went through an obstacle it now weighs the way round (corridor-64 by type: two lines through
the wall, the slower flown alone round it 1.84 B; measured by ``benchmarks/why_by_type.py``).
The reach times depend on the start or the goal alone, so each is computed once per window (n per type
and window, not n squared).
"""

from __future__ import annotations

import numpy as np

from proxplan.planfile import Scenario
from proxplan.planner.bounds import Window, reach_through_s, slabs, window

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
    reach: dict[tuple[str, int, tuple[int, float, float]], float] = {}  # (start/goal, vehicle, window) -> s

    def win(axis: int, coord: float, rb: float) -> tuple[tuple[int, float, float], Window]:
        key = (axis, round(coord, 9), round(rb, 9))
        if key not in windows:
            windows[key] = window(scenario, axis, coord, rb)
        return key, windows[key]

    def reach_s(end: str, a: int, key: tuple[int, float, float], w: Window) -> float:
        got = reach.get((end, a, key))
        if got is None:
            point = starts[a] if end == "start" else goals[a]
            got = reach[(end, a, key)] = reach_through_s(point, w, tasks[a].kinematic_limits)
        return got

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
            (k_near, w_near), (k_far, w_far) = win(k, near, rb), win(k, far, rb)
            leave = reach_s("start", int(i), k_near, w_near)
            inside = (slab.hi_m - slab.lo_m) / lim.max_speed_mps
            for g in np.flatnonzero(across[i]):
                # the goal's reach with vehicle i's limits: vehicles of one type share them (assign.py)
                arrive = (
                    reach_through_s(goals[g], w_far, lim)
                    if tasks[g].kinematic_limits != lim
                    else reach_s("goal", int(g), k_far, w_far)
                )
                out[i, g] = max(out[i, g], leave + inside + arrive)
    return out
