"""A route for one vehicle through the others' space-time: a wavefront on a fine horizontal grid.

The vehicle is treated as moving one grid cell (8-connected, ``CELL_M``) or waiting per layer of
``layer_s`` = cell diagonal / (``SPEED_FRACTION`` x its speed limit). Each layer of the grid marks
the cells round any other vehicle during that layer's time span (their track samples, swept; parked
vehicles for good; predicted tracks of vehicles not planned yet until they vanish), so
column-exclusive downwash is 2-D here. With ``heights`` (off by default) a sample's disc is the
pair's horizontal keep-out at the heights the route flies at within its reach (the route's height
is a function of the place, :func:`route_heights`: two layers of traffic 0.5 m apart pass within
the downwash cut-off, not the separation sphere), grown by half a cell's diagonal so that it holds
every cell centre in conflict with the sample itself; without, the widest keep-out at any height
difference round the sample's cell (the pipeline's; docs/planner.md, issue 37 round 10C). Each
sample's disc radius is kept with the sample in the lazy marking below. The set of cells reachable
at layer t+1 is the
8-neighbourhood dilation of the set at layer t, restricted to cells free in both layers (numpy
boolean shifts: the whole search is a few array operations per layer). The first layer at which the
goal cell is reached and stays free to the horizon gives the route; backtracking prefers waiting.
Layers are marked only as far as the front comes (the goal's and the start's cells read at every
layer from the marks' list), and each layer is spread only over the bounding box of the cells
reached at the layer before, grown by one: the same reached cells for less work (tested against
the whole grid).

This is a guide, not a trajectory: the route's corners and waiting places, simplified to within a
cell (Douglas-Peucker: the grid's staircase is not part of the route), become the waypoints of
:func:`proxplan.planner.swarm.chain.time_chain`, which times them exactly against the same tracks
(the grid is coarse where the keep-outs are sharp).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.tracks import GRID_DT_S

CELL_M = 0.075  # grid cell, m
SPEED_FRACTION = 0.8  # the route's pace, as a fraction of the vehicle's speed limit
MARGIN_M = 2.0  # the grid covers the start-goal box grown by this much (clipped to the free box), m
_NEIGHBOURS = ((0, 0), (1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (-1, -1), (1, -1), (-1, 1))


def margin_box(problem, start_m: np.ndarray, goal_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The start-goal box grown by ``MARGIN_M`` (clipped to the free box): (lo, hi) (2,), m."""
    lo = np.maximum(np.minimum(start_m, goal_m)[:2] - MARGIN_M, problem.lo_m[:2])
    hi = np.minimum(np.maximum(start_m, goal_m)[:2] + MARGIN_M, problem.hi_m[:2])
    return lo, hi


def route_box(problem, start_m: np.ndarray, goal_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The horizontal box (lo, hi) (2,), m, that a route from ``start_m`` to ``goal_m`` stays in:
    :func:`margin_box`, or the whole free box when the straight line between them is not
    statically free (:func:`wave_route` then searches there when the margin box holds no route:
    the way round a wall may lie farther out, as for corridor-256's far rows, 3 m beyond it)."""
    if not problem.segment_free(start_m, goal_m):
        return problem.lo_m[:2].copy(), problem.hi_m[:2].copy()
    return margin_box(problem, start_m, goal_m)


def _disc(radius_cells: float) -> tuple[np.ndarray, np.ndarray]:
    """The offsets (i, j) with i^2 + j^2 < ``radius_cells``^2 (two (k,) int arrays)."""
    return _disc_of(_disc_key(radius_cells))


def _disc_key(radius_cells: float) -> int:
    """The integer K = ceil(radius^2): i^2 + j^2 < radius^2 exactly when i^2 + j^2 < K (both sides of
    the first are compared as floats, the left an integer), so radii of one K mark the same disc."""
    return math.ceil(radius_cells * radius_cells)


@functools.lru_cache(maxsize=256)
def _disc_of(key: int) -> tuple[np.ndarray, np.ndarray]:
    n = math.isqrt(max(key - 1, 0))
    ix, iy = np.meshgrid(np.arange(-n, n + 1), np.arange(-n, n + 1), indexing="ij")
    m = ix * ix + iy * iy < key
    return ix[m], iy[m]


def static_grid(problem, gx: np.ndarray, gy: np.ndarray, z_m: float) -> np.ndarray:
    """(nx, ny) bool: the cells of the grid ``gx`` x ``gy`` (m) at height ``z_m`` whose centre and
    first half of every move to a neighbour stay in the static free space (sampled at a quarter and
    half a cell); the same for every vehicle and every state of the others, so
    :func:`wave_route` asks it once per grid and height (``SwarmProblem.static_memo``)."""
    h = CELL_M
    free = np.ones((gx.size, gy.size), dtype=bool)
    for fx, fy in ((0, 0), (1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (1, -1), (-1, 1), (-1, -1)):
        for f in (0.25, 0.5):  # the cell and the first half of every move out of it stay free
            free &= problem.static_free_grid(gx + f * fx * h, gy + f * fy * h, z_m)
    free.flags.writeable = False  # shared by every route on this grid
    return free


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
    occupied, free_static = _marks(occ, agent, start_m, goal_m, box, pace=pace, grow_m=grow_m, heights=heights)
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
    return _waypoints(cells, lo, h, start_m, goal_m, heights=heights)


def _marks(occ, agent, start_m, goal_m, box, *, pace: float, grow_m: float, heights: bool):
    """(the others' marks on the grid over ``box`` ((lo, hi) (2,), m; cell i at lo + i ``CELL_M``),
    not yet spread over the layers (:class:`_Occupied`); the cells statically free (nx, ny) bool)."""
    p = occ.problem
    lim = p.limits[agent]
    h = CELL_M
    layer_s = h * math.sqrt(2.0) / (pace * lim.max_speed_mps)
    n_layers = max(2, int(occ.horizon * GRID_DT_S / layer_s))
    lo, hi = box
    nx = int(math.ceil((hi[0] - lo[0]) / h)) + 1
    ny = int(math.ceil((hi[1] - lo[1]) / h)) + 1
    gx = lo[0] + np.arange(nx) * h
    gy = lo[1] + np.arange(ny) * h
    z_mid = 0.5 * (start_m[2] + goal_m[2])
    grid_key = ("wave grid", np.asarray(lo, dtype=float).tobytes(), nx, ny, float(z_mid))
    free_static = p.static_memo.get(grid_key, lambda: static_grid(p, gx, gy, z_mid))
    occupied = _Occupied(n_layers, nx, ny)
    ta = int(p.type_index[agent])
    per_layer = layer_s / GRID_DT_S
    box_lo = np.r_[lo, -np.inf]
    box_hi = np.r_[hi, np.inf]
    for tr in occ.near(box_lo, box_hi, agent):
        ko = p.keepouts[(ta, tr.type)]
        P = tr.positions_m
        k = np.arange(P.shape[0])
        lay = np.floor(k / per_layer + 0.5).astype(np.int64)
        cx = np.round((P[:, 0] - lo[0]) / h).astype(np.int64)
        cy = np.round((P[:, 1] - lo[1]) / h).astype(np.int64)
        if heights:  # a radius per sample: the keep-out at the heights the route flies at near it
            radii = _radii_cells(ko, P, start_m, goal_m, grow_m)
            keys = np.ceil(radii * radii)  # _disc_key of each: the samples of one disc marked together
            for k in np.unique(keys).tolist():
                at = np.flatnonzero(keys == k)
                occupied.add(float(radii[at[0]]), *_distinct(lay[at], cx[at], cy[at]))
            radius_last = float(radii[-1])
        else:  # the widest keep-out at any height difference, round the sample's cell
            radius_last = (ko.reach_xy_m + grow_m) / h
            occupied.add(radius_last, *_distinct(lay, cx, cy))
        last = int(lay[-1])
        if last < n_layers and not tr.vanishes:  # parked for good
            occupied.park(radius_last, last, int(cx[-1]), int(cy[-1]))
    return occupied, free_static


def _distinct(lay: np.ndarray, cx: np.ndarray, cy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The distinct (layer, cell x, cell y) of samples, sorted (one 1-D key each; cells may lie
    outside the grid)."""
    x0, y0 = int(cx.min()), int(cy.min())
    span_x, span_y = int(cx.max()) - x0 + 1, int(cy.max()) - y0 + 1
    key = np.unique((lay * span_x + (cx - x0)) * span_y + (cy - y0))
    key_l, rem = np.divmod(key, span_x * span_y)
    key_x, key_y = np.divmod(rem, span_y)
    return key_l, key_x + x0, key_y + y0


def free_layers(
    occ, agent, start_m, goal_m, box, *, pace: float = SPEED_FRACTION, grow_m: float = 0.0, heights: bool = False
) -> np.ndarray:
    """(layers, nx, ny) bool: the cells of the grid over ``box`` ((lo, hi) (2,), m; cell i at
    lo + i ``CELL_M``) free of the others at every layer (see module), all layers marked (the
    search marks only as far as its front comes)."""
    occupied, free_static = _marks(occ, agent, start_m, goal_m, box, pace=pace, grow_m=grow_m, heights=heights)
    occupied.mark_upto(occupied.shape[0])
    return ~occupied.layers & free_static[None]


class _Occupied:
    """The wavefront's occupied cells, (n_layers, nx, ny) bool, marked only as far as asked: each
    entry is a disc of ``radius`` cells (the offsets (i, j) with i^2 + j^2 < radius^2) around a
    cell at a layer (cells and layers outside the grid are ignored), or around a cell from a layer
    on for good (a parked vehicle). :meth:`mark_upto` marks the layers before n in :attr:`layers`;
    :meth:`column` gives one cell's occupancy at every layer from the entries, the same as marking
    every layer and reading it there. The front seldom needs the whole horizon (it reaches the goal
    or dies first), so layers past it are never marked."""

    FIRST_CHUNK = 32  # layers marked at the first call; each later call marks at least as many again

    def __init__(self, n_layers: int, nx: int, ny: int):
        self.shape = (n_layers, nx, ny)
        self.layers = np.zeros(self.shape, dtype=bool)
        self.done = 0  # layers [0, done) are marked
        self._keys: dict[int, list[tuple[np.ndarray, np.ndarray, np.ndarray]]] = {}  # disc key -> samples
        self._sorted: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] | None = None
        self._parked: list[tuple[int, int, int, int]] = []  # (disc key, layer, cell x, cell y)

    def add(self, radius: float, layer: np.ndarray, cx: np.ndarray, cy: np.ndarray) -> None:
        # kept by the disc's key (_disc_key): radii that mark the same disc are marked together
        self._keys.setdefault(_disc_key(radius), []).append((layer, cx, cy))
        self._sorted = None

    def park(self, radius: float, layer: int, cx: int, cy: int) -> None:
        self._parked.append((_disc_key(radius), layer, cx, cy))

    def _by_layer(self) -> dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]]:
        if self._sorted is None:
            self._sorted = {}
            for key, parts in self._keys.items():
                L, X, Y = (np.concatenate([q[i] for q in parts]) for i in range(3))
                o = np.argsort(L, kind="stable")
                self._sorted[key] = (L[o], X[o], Y[o])
        return self._sorted

    def mark_upto(self, n: int) -> None:
        """Mark the layers before ``n`` (at least, in chunks)."""
        n_layers, nx, ny = self.shape
        if n <= self.done:
            return
        n = min(n_layers, max(n, self.done + max(self.FIRST_CHUNK, self.done)))
        for key, (L, X, Y) in self._by_layer().items():
            i0, i1 = np.searchsorted(L, [self.done, n])
            ox, oy = _disc_of(key)
            X_ = X[i0:i1, None] + ox[None]
            Y_ = Y[i0:i1, None] + oy[None]
            L_ = np.broadcast_to(L[i0:i1, None], X_.shape)
            ok = (L_ >= 0) & (X_ >= 0) & (X_ < nx) & (Y_ >= 0) & (Y_ < ny)
            self.layers[L_[ok], X_[ok], Y_[ok]] = True
        for key, last, cx, cy in self._parked:
            if last < n:
                ox, oy = _disc_of(key)
                X_, Y_ = cx + ox, cy + oy
                ok = (X_ >= 0) & (X_ < nx) & (Y_ >= 0) & (Y_ < ny)
                self.layers[max(last, self.done) : n, X_[ok], Y_[ok]] = True
        self.done = n

    def column(self, x: int, y: int) -> np.ndarray:
        """(n_layers,) bool: whether cell (x, y) of the grid is occupied at each layer."""
        n_layers = self.shape[0]
        out = np.zeros(n_layers, dtype=bool)
        for key, parts in self._keys.items():
            for L, X, Y in parts:
                dx, dy = x - X, y - Y
                hit = L[(dx * dx + dy * dy < key) & (L >= 0) & (L < n_layers)]
                out[hit] = True
        for key, last, cx, cy in self._parked:
            if (x - cx) ** 2 + (y - cy) ** 2 < key:
                out[max(last, 0) :] = True
        return out


def dilated(cur: np.ndarray) -> np.ndarray:
    """(nx, ny) bool: the cells of ``cur`` and their 8 neighbours (a new array)."""
    nxt = cur.copy()
    nxt[1:, :] |= cur[:-1, :]
    nxt[:-1, :] |= cur[1:, :]
    nxt[:, 1:] |= cur[:, :-1]
    nxt[:, :-1] |= cur[:, 1:]
    nxt[1:, 1:] |= cur[:-1, :-1]
    nxt[:-1, :-1] |= cur[1:, 1:]
    nxt[1:, :-1] |= cur[:-1, 1:]
    nxt[:-1, 1:] |= cur[1:, :-1]
    return nxt


def _spread(
    reach: np.ndarray,
    occupied: _Occupied,
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


def _radii_cells(ko, P: np.ndarray, start_m: np.ndarray, goal_m: np.ndarray, grow_m: float) -> np.ndarray:
    """(S,) the disc radius, in cells, marked round each
    sample ``P`` (S, 3), m, of another vehicle with keep-out ``ko``: the widest horizontal keep-out
    (:meth:`~proxplan.planner.swarm.keepout.KeepOut.horizontal_radius_m`) over the heights
    (:func:`route_heights`) the route can have within its reach (every height between start and
    goal when :func:`route_heights` is None); the height bands are widened to the keep-out's table
    steps, so few distinct bands are asked."""
    z_lo, z_hi = min(start_m[2], goal_m[2]), max(start_m[2], goal_m[2])
    u = np.asarray(goal_m[:2], dtype=float) - start_m[:2]
    along = ko.reach_xy_m * u / max(float(np.sqrt(u @ u)), 1e-300)  # the reach, along the start-goal line
    za = route_heights(start_m, goal_m, P[:, :2] - along)  # the route's heights a reach before and after
    zb = route_heights(start_m, goal_m, P[:, :2] + along)
    if z_hi - z_lo > 0.0 and za is not None and zb is not None:
        z_lo, z_hi = np.minimum(za, zb), np.maximum(za, zb)
    step = ko.step_m
    lo_k = np.floor((P[:, 2] - z_hi) / step).astype(np.int64)  # d_z = z_b - z_a, widened to table steps
    hi_k = np.ceil((P[:, 2] - z_lo) / step).astype(np.int64)
    bands, inverse = np.unique(np.column_stack([lo_k, hi_k]), axis=0, return_inverse=True)
    r_m = np.array([ko.horizontal_radius_m(a * step, b * step) for a, b in bands.tolist()])
    # + half a cell's diagonal: the disc is centred on the sample's cell, up to that far from the sample,
    # so it holds every cell centre within the keep-out of the sample itself
    cells = (r_m + grow_m) / CELL_M + 0.5 * math.sqrt(2.0)
    return cells[np.asarray(inverse).reshape(-1)]


def _waypoints(
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
