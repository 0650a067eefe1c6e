"""The others' marks on the wavefront's grid (:mod:`proxplan.planner.swarm.wave`), layer by layer.

Each layer of the grid marks the cells round any other vehicle during that layer's time span (their
track samples, swept; parked vehicles for good; predicted tracks of vehicles not planned yet until
they vanish), so column-exclusive downwash is 2-D here. With ``heights`` a sample's disc is the pair's
horizontal keep-out at the heights the route flies at within its reach
(:func:`proxplan.planner.swarm.wave_grid.route_heights`: two layers of traffic 0.5 m apart pass within
the downwash cut-off, not the separation sphere), grown by half a cell's diagonal so that it holds
every cell centre in conflict with the sample itself; without, the widest keep-out at any height
difference round the sample's cell (docs/planner.md, issue 37 round 10C). Each sample's disc radius
is kept with the sample, and layers are marked only as far as asked (:class:`OccupiedCells`): the
front seldom needs the whole horizon.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from proxplan.planner.swarm.tracks import GRID_DT_S
from proxplan.planner.swarm.wave_grid import CELL_M, route_heights, static_grid


def disc_offsets(radius_cells: float) -> tuple[np.ndarray, np.ndarray]:
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


def others_marks(occ, agent, start_m, goal_m, box, *, pace: float, grow_m: float, heights: bool):
    """(the others' marks on the grid over ``box`` ((lo, hi) (2,), m; cell i at lo + i ``CELL_M``),
    not yet spread over the layers (:class:`OccupiedCells`); the cells statically free (nx, ny) bool)."""
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
    occupied = OccupiedCells(n_layers, nx, ny)
    ta = int(p.type_index[agent])
    per_layer = layer_s / GRID_DT_S
    box_lo = np.r_[lo, -np.inf]
    box_hi = np.r_[hi, np.inf]
    near = occ.near(box_lo, box_hi, agent)
    if heights:  # a radius per sample: the keep-out at the heights the route flies at near it
        for tr in near:
            ko = p.keepouts[(ta, tr.type)]
            P = tr.positions_m
            lay, cx, cy = _cells(P, np.arange(P.shape[0]), per_layer, lo, h)
            radii = _radii_cells(ko, P, start_m, goal_m, grow_m)
            keys = np.ceil(radii * radii)  # _disc_key of each: the samples of one disc marked together
            for k in np.unique(keys).tolist():
                at = np.flatnonzero(keys == k)
                occupied.add(float(radii[at[0]]), *_distinct(lay[at], cx[at], cy[at]))
            last = int(lay[-1])
            if last < n_layers and not tr.vanishes:  # parked for good
                occupied.park(float(radii[-1]), last, int(cx[-1]), int(cy[-1]))
        return occupied, free_static
    # without heights every sample of one other type marks the same disc, the widest keep-out at any
    # height difference round the sample's cell: the samples of all the tracks of a type are marked
    # together (the marks are a union: the same layers as track by track), and the cells of every
    # track are found in one pass over their samples laid end to end (round 37A: the same values as
    # track by track, for a few array operations per call instead of a dozen per track)
    if not near:
        return occupied, free_static
    sizes = np.array([tr.positions_m.shape[0] for tr in near])
    first = np.cumsum(sizes) - sizes  # where each track's samples begin
    k = np.arange(int(sizes.sum())) - np.repeat(first, sizes)  # each sample's index in its track
    lay, cx, cy = _cells(np.concatenate([tr.positions_m for tr in near]), k, per_layer, lo, h)
    new = np.ones(lay.size, dtype=bool)  # _changes, track by track: a track's first sample is new
    new[1:] = (lay[1:] != lay[:-1]) | (cx[1:] != cx[:-1]) | (cy[1:] != cy[:-1])
    new[first] = True
    types = np.repeat(np.array([tr.type for tr in near]), sizes)
    ends = first + sizes - 1
    for tr, e in zip(near, ends.tolist()):
        if int(lay[e]) < n_layers and not tr.vanishes:  # parked for good
            radius_last = (p.keepouts[(ta, tr.type)].reach_xy_m + grow_m) / h
            occupied.park(radius_last, int(lay[e]), int(cx[e]), int(cy[e]))
    for tb in dict.fromkeys(tr.type for tr in near):  # the types in the order of their first track
        radius = (p.keepouts[(ta, tb)].reach_xy_m + grow_m) / h
        at = np.flatnonzero(new & (types == tb))
        occupied.add(radius, lay[at], cx[at], cy[at])
    return occupied, free_static


def _cells(P: np.ndarray, k: np.ndarray, per_layer: float, lo, h: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The layer and the grid cell (x, y) of samples ``P`` (S, 3), m, at grid steps ``k`` (S,) of their
    track: layer round(k / ``per_layer``), cell round((p - ``lo``) / ``h``)."""
    lay = np.floor(k / per_layer + 0.5).astype(np.int64)
    cx = np.round((P[:, 0] - lo[0]) / h).astype(np.int64)
    cy = np.round((P[:, 1] - lo[1]) / h).astype(np.int64)
    return lay, cx, cy


def _changes(lay: np.ndarray, cx: np.ndarray, cy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The samples (layer, cell x, cell y) of one track, in time order, without those equal to the one
    before (a vehicle resting, or within one cell for a layer): the same cells as every sample (a
    union), found in one pass instead of a sort."""
    new = np.ones(lay.size, dtype=bool)
    new[1:] = (lay[1:] != lay[:-1]) | (cx[1:] != cx[:-1]) | (cy[1:] != cy[:-1])
    return lay[new], cx[new], cy[new]


def _distinct(lay: np.ndarray, cx: np.ndarray, cy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The distinct (layer, cell x, cell y) of samples, sorted (one 1-D key each; cells may lie
    outside the grid)."""
    x0, y0 = int(cx.min()), int(cy.min())
    span_x, span_y = int(cx.max()) - x0 + 1, int(cy.max()) - y0 + 1
    key = np.unique((lay * span_x + (cx - x0)) * span_y + (cy - y0))
    key_l, rem = np.divmod(key, span_x * span_y)
    key_x, key_y = np.divmod(rem, span_y)
    return key_l, key_x + x0, key_y + y0


def mark_discs(
    buffer: np.ndarray, pad: int, grid: tuple[int, int], key: int, layer: np.ndarray, cx: np.ndarray, cy: np.ndarray
) -> None:
    """Mark the disc of ``key`` (:func:`_disc_key`) round each cell (``layer``, ``cx``, ``cy``) (k,) of a grid
    of ``grid`` = (nx, ny) cells held in ``buffer`` (n_layers, nx + 2 pad, ny + 2 pad) bool, C-contiguous,
    cell (i, j) at [pad + i, pad + j]; ``pad`` at least twice the disc's half-width h (its largest |i|).
    A centre more than h cells off the grid has no disc cell on it and is left out; every other disc
    then lies inside the buffer, so its cells are the centre's flat index plus the disc's flat offsets,
    written at once with no test per cell (round 37A; cells in the padding are never read). The grid's
    cells marked are those of testing each disc cell against the grid's bounds (tested); ``layer``
    must lie in [0, n_layers)."""
    nx, ny = grid
    half = math.isqrt(max(key - 1, 0))
    if pad < 2 * half:
        raise ValueError(f"a padding of {pad} cells cannot hold a disc of half-width {half}")
    near = (cx >= -half) & (cx < nx + half) & (cy >= -half) & (cy < ny + half)  # else no cell on the grid
    if not near.all():
        layer, cx, cy = layer[near], cx[near], cy[near]
    NX, NY = buffer.shape[1], buffer.shape[2]
    ox, oy = _disc_of(key)
    centre = (np.asarray(layer, dtype=np.int64) * NX + (cx + pad)) * NY + (cy + pad)
    buffer.reshape(-1)[centre[:, None] + (ox * NY + oy)[None]] = True


class OccupiedCells:
    """The wavefront's occupied cells, (n_layers, nx, ny) bool, marked only as far as asked: each
    entry is a disc of ``radius`` cells (the offsets (i, j) with i^2 + j^2 < radius^2) around a
    cell at a layer (cells and layers outside the grid are ignored), or around a cell from a layer
    on for good (a parked vehicle). :meth:`mark_upto` marks the layers before n in :attr:`layers`;
    :meth:`column` gives one cell's occupancy at every layer from the entries, the same as marking
    every layer and reading it there. The front seldom needs the whole horizon (it reaches the goal
    or dies first), so layers past it are never marked.

    **Marking by flat offsets** (round 37A). :attr:`layers` is a view of a buffer padded by twice the
    widest disc's half-width on every side (allocated when first asked, once every entry is in), and
    the moving entries are marked by :func:`mark_discs`: the same cells as testing every disc cell
    against the grid's bounds (the definition, tested), for one addition and one write per cell
    instead of a dozen array operations (the marks were 15 % of the plan's CPU on the randomised
    family's random-10 at 64 fixed, 5 % after)."""

    FIRST_CHUNK = 32  # layers marked at the first call; each later call marks at least as many again

    def __init__(self, n_layers: int, nx: int, ny: int):
        self.shape = (n_layers, nx, ny)
        self._layers: np.ndarray | None = None  # the grid's view of the padded buffer (built when first asked)
        self._buffer: np.ndarray | None = None
        self._pad = 0  # cells of padding on each side of the buffer
        self.done = 0  # layers [0, done) are marked
        self._keys: dict[int, list[tuple[np.ndarray, np.ndarray, np.ndarray]]] = {}  # disc key -> samples
        self._sorted: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] | None = None
        self._parked: list[tuple[int, int, int, int]] = []  # (disc key, layer, cell x, cell y)

    @property
    def layers(self) -> np.ndarray:
        """(n_layers, nx, ny) bool: the marks (layers before :attr:`done` complete)."""
        if self._layers is None:
            keys = [*self._keys, *(k for k, _, _, _ in self._parked)]
            half = max((math.isqrt(max(k - 1, 0)) for k in keys), default=0)  # the widest disc's |i|, |j|
            self._pad = pad = 2 * half
            n_layers, nx, ny = self.shape
            self._buffer = np.zeros((n_layers, nx + 2 * pad, ny + 2 * pad), dtype=bool)
            self._layers = self._buffer[:, pad : pad + nx, pad : pad + ny]
        return self._layers

    def add(self, radius: float, layer: np.ndarray, cx: np.ndarray, cy: np.ndarray) -> None:
        # kept by the disc's key (_disc_key): radii that mark the same disc are marked together
        self._add_key(_disc_key(radius))
        self._keys.setdefault(_disc_key(radius), []).append((layer, cx, cy))
        self._sorted = None

    def park(self, radius: float, layer: int, cx: int, cy: int) -> None:
        self._add_key(_disc_key(radius))
        self._parked.append((_disc_key(radius), layer, cx, cy))

    def _add_key(self, key: int) -> None:
        """An entry of disc ``key`` comes in: the buffer's padding must hold its disc."""
        if self._layers is not None and 2 * math.isqrt(max(key - 1, 0)) > self._pad:
            raise ValueError("an entry wider than the padding came in after the marks were begun")

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
        layers = self.layers
        buf, pad = self._buffer, self._pad
        assert buf is not None  # built with layers
        n = min(n_layers, max(n, self.done + max(self.FIRST_CHUNK, self.done)))
        for key, (L, X, Y) in self._by_layer().items():
            i0, i1 = np.searchsorted(L, [self.done, n])
            if i1 > i0:
                mark_discs(buf, pad, (nx, ny), key, L[i0:i1], X[i0:i1], Y[i0:i1])
        for key, last, cx, cy in self._parked:
            if last < n:
                ox, oy = _disc_of(key)
                X_, Y_ = cx + ox, cy + oy
                ok = (X_ >= 0) & (X_ < nx) & (Y_ >= 0) & (Y_ < ny)
                layers[max(last, self.done) : n, X_[ok], Y_[ok]] = True
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
