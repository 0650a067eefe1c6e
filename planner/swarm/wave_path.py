"""A wavefront's cell route (:mod:`proxplan.planner.swarm.wave`) as waypoints: its corners and
waiting places, simplified to within a cell (Douglas-Peucker: the grid's staircase is not part of the
route), with the exact start and goal and the height of :func:`~proxplan.planner.swarm.wave_grid.route_heights`
(or linear in the distance flown).
"""

from __future__ import annotations

import math

import numpy as np

from proxplan.planner.swarm.wave_grid import route_heights


def cell_route_waypoints(
    cells: list[tuple[int, int]], lo: np.ndarray, h: float, start_m: np.ndarray, goal_m: np.ndarray, *, heights: bool
):
    """Corners and waiting places of a cell route as 3-D waypoints, exact start and goal."""
    keep = [0]
    for k in range(1, len(cells) - 1):
        a, b, c = cells[k - 1], cells[k], cells[k + 1]
        if (b[0] - a[0], b[1] - a[1]) != (c[0] - b[0], c[1] - b[1]):
            keep.append(k)
    keep.append(len(cells) - 1)
    keep = _simplified(np.array(cells, dtype=float), keep, tolerance=1.0)  # within one cell
    xy: list[np.ndarray] = []
    for k in keep:
        q = lo + np.array(cells[k], dtype=float) * h
        if not xy or float(np.linalg.norm(xy[-1] - q)) > 1e-9:
            xy.append(q)
    xy[0] = start_m[:2].copy()
    if len(xy) == 1:
        xy.append(goal_m[:2].copy())
    xy[-1] = goal_m[:2].copy()
    pts = np.array(xy)
    s = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))]
    z = route_heights(start_m, goal_m, pts) if heights else None
    if z is None:
        z = start_m[2] + (goal_m[2] - start_m[2]) * (s / s[-1] if s[-1] > 0 else s)
    out = np.column_stack([pts, z])
    keep_pts = [out[0]]
    for q in out[1:]:
        if float(np.linalg.norm(q - keep_pts[-1])) > 1e-9:
            keep_pts.append(q)
    return np.array(keep_pts if len(keep_pts) > 1 else [out[0], out[-1]])


def _simplified(cells: np.ndarray, keep: list[int], *, tolerance: float) -> list[int]:
    """Douglas-Peucker over the kept corners of a cell route (cells (n, 2), in cells), never
    dropping a place where the route waits (a repeated cell)."""
    waits = {k for k in keep if 0 < k < len(cells) - 1 and np.array_equal(cells[k], cells[k - 1])}
    out: list[int] = []

    def rec(i: int, j: int) -> None:
        a, b = cells[keep[i]], cells[keep[j]]
        ab = b - a
        worst, at = -1.0, -1
        for m in range(i + 1, j):
            p = cells[keep[m]]
            if keep[m] in waits:
                worst, at = math.inf, m
                break
            L2 = float(ab @ ab)
            s = 0.0 if L2 == 0.0 else min(1.0, max(0.0, float((p - a) @ ab) / L2))
            dist = float(np.linalg.norm(p - a - s * ab))
            if dist > worst:
                worst, at = dist, m
        if at >= 0 and worst > tolerance:
            rec(i, at)
            out.append(keep[at])
            rec(at, j)

    out.append(keep[0])
    rec(0, len(keep) - 1)
    out.append(keep[-1])
    return sorted(set(out))
