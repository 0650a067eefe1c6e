"""The wavefront's grid (:mod:`proxplan.planner.swarm.wave`): a horizontal grid of ``CELL_M`` cells over
the box a route may use, the cells statically free on it, and the height a route flies at each place.

The box is the start-goal box grown by ``MARGIN_M`` (:func:`margin_box`), or the whole free box when
the straight line crosses a wall (:func:`route_box`). A route's height is a function of the place
(:func:`route_heights`), so the discs that mark the others (:mod:`proxplan.planner.swarm.wave_marks`)
can be as wide as the keep-out at the heights the route flies at there.
"""

from __future__ import annotations

import numpy as np

CELL_M = 0.075  # grid cell, m
MARGIN_M = 2.0  # the grid covers the start-goal box grown by this much (clipped to the free box), m


def margin_box(problem, start_m: np.ndarray, goal_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The start-goal box grown by ``MARGIN_M`` (clipped to the free box): (lo, hi) (2,), m."""
    lo = np.maximum(np.minimum(start_m, goal_m)[:2] - MARGIN_M, problem.lo_m[:2])
    hi = np.minimum(np.maximum(start_m, goal_m)[:2] + MARGIN_M, problem.hi_m[:2])
    return lo, hi


def route_box(problem, start_m: np.ndarray, goal_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The horizontal box (lo, hi) (2,), m, that a route from ``start_m`` to ``goal_m`` stays in:
    :func:`margin_box`, or the whole free box when the straight line between them is not
    statically free (:func:`~proxplan.planner.swarm.wave.wave_route` then searches there when the margin box holds no route:
    the way round a wall may lie farther out, as for corridor-256's far rows, 3 m beyond it)."""
    if not problem.segment_free(start_m, goal_m):
        return problem.lo_m[:2].copy(), problem.hi_m[:2].copy()
    return margin_box(problem, start_m, goal_m)


def static_grid(problem, gx: np.ndarray, gy: np.ndarray, z_m: float) -> np.ndarray:
    """(nx, ny) bool: the cells of the grid ``gx`` x ``gy`` (m) at height ``z_m`` whose centre and
    first half of every move to a neighbour stay in the static free space (sampled at a quarter and
    half a cell); the same for every vehicle and every state of the others, so
    :func:`~proxplan.planner.swarm.wave.wave_route` asks it once per grid and height (``SwarmProblem.static_memo``)."""
    h = CELL_M
    free = np.ones((gx.size, gy.size), dtype=bool)
    for fx, fy in ((0, 0), (1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (1, -1), (-1, 1), (-1, -1)):
        for f in (0.25, 0.5):  # the cell and the first half of every move out of it stay free
            free &= problem.static_free_grid(gx + f * fx * h, gy + f * fy * h, z_m)
    free.flags.writeable = False  # shared by every route on this grid
    return free


def route_heights(start_m: np.ndarray, goal_m: np.ndarray, xy_m: np.ndarray) -> np.ndarray | None:
    """Heights (n,), m, of a route's points ``xy_m`` (n, 2): the start's height, then linear in the
    progress along the horizontal start-goal line (the projection, clamped to the line's ends), the
    goal's at and beyond it - so a point's height does not depend on the way the route took to it,
    and a vehicle waiting beside its start stays at its start's height. None when start and goal
    lie within a cell horizontally (no line to project on; the height then runs with the distance
    flown)."""
    u = np.asarray(goal_m[:2], dtype=float) - start_m[:2]
    length2 = float(u @ u)
    if length2 < CELL_M * CELL_M:
        return None
    f = np.clip((np.asarray(xy_m, dtype=float) - start_m[:2]) @ u / length2, 0.0, 1.0)
    return start_m[2] + (goal_m[2] - start_m[2]) * f
