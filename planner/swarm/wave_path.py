"""A wavefront's cell route (:mod:`proxplan.planner.swarm.wave`) as waypoints: its corners and
waiting places, simplified to within a cell (Douglas-Peucker: the grid's staircase is not part of the
route), with the exact start and goal and the height of :func:`~proxplan.planner.swarm.wave_grid.route_heights`
(or linear in the distance flown).

A simplified leg may cut up to a cell into an inflated obstacle that the cells themselves kept clear of
(the wavefront's cells are statically free, :func:`~proxplan.planner.swarm.wave_grid.static_grid`, but a
chord within a cell of them need not be): every leg whose straight segment is not statically free
(``segment_free``, the test :func:`~proxplan.planner.swarm.chain.time_chain` flies a leg by) gets back
the corner of the cell route farthest from it between its ends, until every leg is free or no corner is
left to put back. A route whose legs are not free can never be timed, so a vehicle whose straight line
crossed the pillar had no track at all, not even alone (issue 37, round 36S: pillar-128 by type, its
prioritised passes gave up on such a vehicle).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from proxplan.planner.swarm.wave_grid import route_heights


def cell_route_waypoints(
    cells: list[tuple[int, int]],
    lo: np.ndarray,
    h: float,
    start_m: np.ndarray,
    goal_m: np.ndarray,
    *,
    heights: bool,
    segment_free: Callable[[np.ndarray, np.ndarray], bool] | None = None,
):
    """Corners and waiting places of a cell route as 3-D waypoints, exact start and goal; with
    ``segment_free`` (p0, p1 -> whether the straight segment is statically free) the corners a leg
    needs to stay statically free are put back (see module)."""
    corners = [0]
    for k in range(1, len(cells) - 1):
        a, b, c = cells[k - 1], cells[k], cells[k + 1]
        if (b[0] - a[0], b[1] - a[1]) != (c[0] - b[0], c[1] - b[1]):
            corners.append(k)
    corners.append(len(cells) - 1)
    grid = np.array(cells, dtype=float)
    keep = _simplified(grid, corners, tolerance=1.0)  # within one cell
    out, spans = _waypoints(cells, keep, lo, h, start_m, goal_m, heights=heights)
    while segment_free is not None:
        grown = sorted(set(keep) | _corners_back(grid, corners, out, spans, segment_free))
        if len(grown) == len(keep):  # every leg free, or no corner left to put back: kept corners only grow
            break
        keep = grown
        out, spans = _waypoints(cells, keep, lo, h, start_m, goal_m, heights=heights)
    return out


def _corners_back(
    grid: np.ndarray,
    corners: list[int],
    points: np.ndarray,
    spans: list[tuple[int, int]],
    segment_free: Callable[[np.ndarray, np.ndarray], bool],
) -> set[int]:
    """For each leg of ``points`` whose segment is not statically free, the corner (of ``corners``, cell
    indices) strictly between the cells of its ends (``spans``: the first and last cell of each point)
    farthest from its chord in cells (Douglas-Peucker's choice; ties the first); the empty set when
    every leg is free or none has a corner left between its ends."""
    added: set[int] = set()
    for leg in range(len(points) - 1):
        i, j = spans[leg][1], spans[leg + 1][0]
        inner = [k for k in corners if i < k < j]
        if not inner or segment_free(points[leg], points[leg + 1]):
            continue
        added.add(max(inner, key=lambda k: (_off_chord(grid[k], grid[i], grid[j]), -k)))
    return added


def _off_chord(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    """Distance of the point ``p`` from the segment ``a`` -> ``b`` (any unit)."""
    ab = b - a
    L2 = float(ab @ ab)
    s = 0.0 if L2 == 0.0 else min(1.0, max(0.0, float((p - a) @ ab) / L2))
    return float(np.linalg.norm(p - a - s * ab))


def _waypoints(
    cells: list[tuple[int, int]],
    keep: list[int],
    lo: np.ndarray,
    h: float,
    start_m: np.ndarray,
    goal_m: np.ndarray,
    *,
    heights: bool,
) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """The 3-D waypoints of the cells ``keep`` of a cell route, exact start and goal (see module), and
    per waypoint the first and last of its cells (a point repeated is kept once)."""
    xy: list[np.ndarray] = []
    spans: list[list[int]] = []
    for k in keep:
        q = lo + np.array(cells[k], dtype=float) * h
        if not xy or float(np.linalg.norm(xy[-1] - q)) > 1e-9:
            xy.append(q)
            spans.append([k, k])
        else:
            spans[-1][1] = k
    xy[0] = start_m[:2].copy()
    if len(xy) == 1:
        xy.append(goal_m[:2].copy())
        spans = [[keep[0], keep[0]], [keep[-1], keep[-1]]]
    xy[-1] = goal_m[:2].copy()
    pts = np.array(xy)
    s = np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))]
    z = route_heights(start_m, goal_m, pts) if heights else None
    if z is None:
        z = start_m[2] + (goal_m[2] - start_m[2]) * (s / s[-1] if s[-1] > 0 else s)
    out = np.column_stack([pts, z])
    keep_pts, keep_spans = [out[0]], [spans[0]]
    for q, span in zip(out[1:], spans[1:]):
        if float(np.linalg.norm(q - keep_pts[-1])) > 1e-9:
            keep_pts.append(q)
            keep_spans.append(span)
        else:
            keep_spans[-1] = [keep_spans[-1][0], span[1]]
    if len(keep_pts) == 1:
        return np.array([out[0], out[-1]]), [(spans[0][0], spans[0][0]), (spans[-1][1], spans[-1][1])]
    return np.array(keep_pts), [(a, b) for a, b in keep_spans]


def _simplified(cells: np.ndarray, keep: list[int], *, tolerance: float) -> list[int]:
    """Douglas-Peucker over the kept corners of a cell route (cells (n, 2), in cells), never
    dropping a place where the route waits (a repeated cell)."""
    waits = {k for k in keep if 0 < k < len(cells) - 1 and np.array_equal(cells[k], cells[k - 1])}
    out: list[int] = []

    def rec(i: int, j: int) -> None:
        a, b = cells[keep[i]], cells[keep[j]]
        worst, at = -1.0, -1
        for m in range(i + 1, j):
            if keep[m] in waits:
                worst, at = math.inf, m
                break
            dist = _off_chord(cells[keep[m]], a, b)
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
