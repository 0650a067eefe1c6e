"""A route for one vehicle through the others' space-time: a wavefront on a fine horizontal grid.

The vehicle is treated as moving one grid cell (8-connected, ``CELL_M``) or waiting per layer of
``layer_s`` = cell diagonal / (``SPEED_FRACTION`` x its speed limit). The grid and the route's
heights are :mod:`~proxplan.planner.swarm.wave_grid`; the others' marks on each layer (discs round
their samples, marked only as far as the front comes) are :mod:`~proxplan.planner.swarm.wave_marks`.
The set of cells reachable at layer t+1 is the 8-neighbourhood dilation of the set at layer t,
restricted to cells free in both layers (numpy boolean shifts: the whole search is a few array
operations per layer). The first layer at which the goal cell is reached and stays free to the
horizon gives the route; backtracking prefers waiting. Each layer is spread only over the bounding
box of the cells reached at the layer before, grown by one: the same reached cells for less work
(tested against the whole grid).

This is a guide, not a trajectory: the route's corners and waiting places, simplified to within a
cell with every leg kept statically free (:mod:`~proxplan.planner.swarm.wave_path`), become the waypoints of
:func:`proxplan.planner.swarm.chain.time_chain`, which times them exactly against the same tracks
(the grid is coarse where the keep-outs are sharp).
"""

from __future__ import annotations

import numpy as np

from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.wave_grid import CELL_M, margin_box, route_box
from proxplan.planner.swarm.wave_marks import OccupiedCells, others_marks
from proxplan.planner.swarm.wave_path import cell_route_waypoints

SPEED_FRACTION = 0.8  # the route's pace, as a fraction of the vehicle's speed limit
_NEIGHBOURS = ((0, 0), (1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (-1, -1), (1, -1), (-1, 1))


def wave_route(
    occ: Occupancy,
    agent: int,
    start_m: np.ndarray,
    goal_m: np.ndarray,
    *,
    pace: float = SPEED_FRACTION,
    grow_m: float = 0.0,
    heights: bool = False,
) -> np.ndarray | None:
    """Waypoints (m+1, 3) of a route from start to goal through the others' space-time (see
    module; the height runs linearly with the distance flown), or None when the wavefront dies or
    never reaches a goal that stays free. ``pace``: fraction of the speed limit; ``grow_m``: extra
    keep-out radius, m (a slower, wider route leaves the exact timing more room). The search
    covers :func:`margin_box`, then, when that holds no route, :func:`route_box` if larger. Asked
    again against the same tracks (:meth:`Occupancy.content_key`) with the same arguments, the
    answer is given back, not searched again (:mod:`proxplan.planner.swarm.memo`)."""
    s = np.asarray(start_m, dtype=float)
    g = np.asarray(goal_m, dtype=float)
    key = ("wave", occ.content_key(), agent, s.tobytes(), g.tobytes(), pace, grow_m, heights)
    got = occ.problem.memo.get(key, lambda: _wave_route(occ, agent, s, g, pace=pace, grow_m=grow_m, heights=heights))
    return None if got is None else got.copy()


def _wave_route(
    occ: Occupancy, agent: int, start_m: np.ndarray, goal_m: np.ndarray, *, pace: float, grow_m: float, heights: bool
):
    """:func:`wave_route` searched."""
    p = occ.problem
    small = margin_box(p, start_m, goal_m)
    got = _wave_in_box(occ, agent, start_m, goal_m, small, pace=pace, grow_m=grow_m, heights=heights)
    if got is None:
        large = route_box(p, start_m, goal_m)
        if not (np.array_equal(large[0], small[0]) and np.array_equal(large[1], small[1])):
            got = _wave_in_box(occ, agent, start_m, goal_m, large, pace=pace, grow_m=grow_m, heights=heights)
    return got


def _wave_in_box(occ, agent, start_m, goal_m, box, *, pace: float, grow_m: float, heights: bool) -> np.ndarray | None:
    """:func:`wave_route` on the grid over ``box`` ((lo, hi) (2,), m)."""
    occupied, free_static = others_marks(occ, agent, start_m, goal_m, box, pace=pace, grow_m=grow_m, heights=heights)
    lo = np.asarray(box[0], dtype=float)
    h = CELL_M
    n_layers, nx, ny = occupied.shape
    sx, sy = (int(v) for v in np.round((start_m[:2] - lo) / h))
    gx_, gy_ = (int(v) for v in np.round((goal_m[:2] - lo) / h))
    if occupied.column(sx, sy)[0] or not free_static[sx, sy]:
        return None
    goal_free = ~occupied.column(gx_, gy_) & free_static[gx_, gy_]
    blocked = np.flatnonzero(~goal_free)
    hold_from = int(blocked[-1]) + 1 if blocked.size else 0
    if hold_from >= n_layers:
        return None
    reach = np.zeros((n_layers, nx, ny), dtype=bool)
    t_goal = _spread(reach, occupied, free_static, (sx, sy), (gx_, gy_), hold_from)
    if t_goal is None:
        return None
    cells = [(gx_, gy_)]
    x, y = gx_, gy_
    for t in range(t_goal, 0, -1):
        prev = reach[t - 1]
        for dx, dy in _NEIGHBOURS:
            px, py = x + dx, y + dy
            if 0 <= px < nx and 0 <= py < ny and prev[px, py]:
                x, y = px, py
                break
        cells.append((x, y))
    cells.reverse()
    return cell_route_waypoints(cells, lo, h, start_m, goal_m, heights=heights, segment_free=occ.problem.segment_free)


def free_layers(
    occ, agent, start_m, goal_m, box, *, pace: float = SPEED_FRACTION, grow_m: float = 0.0, heights: bool = False
) -> np.ndarray:
    """(layers, nx, ny) bool: the cells of the grid over ``box`` ((lo, hi) (2,), m; cell i at
    lo + i ``CELL_M``) free of the others at every layer (see module), all layers marked (the
    search marks only as far as its front comes)."""
    occupied, free_static = others_marks(occ, agent, start_m, goal_m, box, pace=pace, grow_m=grow_m, heights=heights)
    occupied.mark_upto(occupied.shape[0])
    return ~occupied.layers & free_static[None]


def dilated(cur: np.ndarray) -> np.ndarray:
    """(nx, ny) bool: the cells of ``cur`` and their 8 neighbours (a new array): the 3 x 3 square is
    the sum of a 3-cell row and a 3-cell column, so the dilation is along x, then along y."""
    row = cur.copy()
    row[1:, :] |= cur[:-1, :]
    row[:-1, :] |= cur[1:, :]
    nxt = row.copy()
    nxt[:, 1:] |= row[:, :-1]
    nxt[:, :-1] |= row[:, 1:]
    return nxt


def _spread(
    reach: np.ndarray,
    occupied: OccupiedCells,
    free_static: np.ndarray,
    start: tuple[int, int],
    goal: tuple[int, int],
    hold_from: int,
) -> int | None:
    """The wavefront: fills ``reach`` (n_layers, nx, ny), False on entry, layer by layer from the
    start cell (a cell is reached at layer t + 1 when a neighbour or itself was reached at layer t
    and it is free at both layers: not ``occupied`` (marked as far as the front has come), free in ``free_static``), and returns the first
    layer t >= ``hold_from`` at which the goal cell is reached (None: the front dies or the layers
    end first). Each layer is computed only on the bounding box of the cells reached at the layer
    before, grown by one cell: every cell outside it stays unreached (it has no reached
    neighbour), so ``reach`` is the same as computed on the whole grid, for a cost that grows with
    the front instead of the grid."""
    n_layers, nx, ny = reach.shape
    gx, gy = goal
    occ = occupied.layers
    reach[0, start[0], start[1]] = True
    x0, x1, y0, y1 = start[0], start[0] + 1, start[1], start[1] + 1  # the reached cells' bounding box
    for t in range(n_layers - 1):
        if t >= hold_from and reach[t, gx, gy]:
            return t
        occupied.mark_upto(t + 2)
        a0, a1, b0, b1 = max(0, x0 - 1), min(nx, x1 + 1), max(0, y0 - 1), min(ny, y1 + 1)
        nxt = dilated(reach[t, a0:a1, b0:b1])
        nxt &= free_static[a0:a1, b0:b1]
        nxt &= ~occ[t + 1, a0:a1, b0:b1]
        nxt &= ~occ[t, a0:a1, b0:b1]
        rows = np.flatnonzero(nxt.any(axis=1))
        if rows.size == 0:
            return None
        cols = np.flatnonzero(nxt.any(axis=0))
        reach[t + 1, a0:a1, b0:b1] = nxt
        x0, x1, y0, y1 = a0 + int(rows[0]), a0 + int(rows[-1]) + 1, b0 + int(cols[0]), b0 + int(cols[-1]) + 1
    return None
