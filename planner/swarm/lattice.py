"""The coordination lattice: horizontal grid on the levels in use, long straight moves, endpoints.

World frame, z up, m. Vertices are the grid points (spacing ``spacing_m`` in x and y, whole
millimetres) on each *level in use* (the distinct heights of starts and goals): downwash columns
make vehicles at different heights exclusive anyway, so no other height helps. The spacing is
chosen between ``SPACING_RANGE`` x the largest keep-out reach so that most starts and goals fall on
vertices; the others become extra vertices joined to their nearest free grid points ("access").
Only statically free vertices and moves count (workspace and obstacles inflated by the widest body
and the tube, :class:`~proxplan.planner.swarm.problem.SwarmProblem`).

Moves from a vertex (:meth:`Lattice.moves`): straight runs of 1..``max_run`` grid edges along the
eight horizontal directions and to the other levels straight above / below, every edge of the run
free; access moves between an off-grid endpoint and its grid points; and a direct move to the
agent's own goal when it is near and the straight line is free. ``dist_to_goal`` is the metric
shortest distance on the unit edges (Dijkstra, scipy), the guide of the search.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import cKDTree

from proxplan.planner.swarm.problem import SwarmProblem

SPACING_RANGE = (0.5, 1.2)  # grid spacing candidates, as multiples of the largest horizontal reach
ACCESS_NEIGHBOURS = 8  # grid points an off-grid endpoint may connect to
ACCESS_RADIUS_FACTOR = 1.5  # ... within this many spacings
XY_DIRECTIONS = ((1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (1, -1), (-1, 1), (-1, -1))


def choose_spacing(points_m: np.ndarray, lo_m: float, hi_m: float) -> tuple[float, np.ndarray]:
    """(spacing, xy residue of the origin), m: among candidate spacings in [lo, hi] (the range's
    points and fractions/multiples of the gaps between the points' coordinates) the one putting
    most points on grid points; ties go to the larger spacing (fewer vertices)."""
    pts = np.asarray(points_m, dtype=float)[:, :2]
    cands = set(np.round(np.linspace(lo_m, hi_m, 6), 3).tolist())
    for axis in (0, 1):
        gaps = np.unique(np.round(np.diff(np.unique(np.round(pts[:, axis], 3))), 3))
        for g in gaps[gaps > 0][:8]:
            for k in range(1, 9):
                for f in (g * k, g / k):
                    if lo_m <= f <= hi_m:
                        cands.add(round(float(f), 3))
    best: tuple | None = None
    for spacing in sorted(cands):
        res = np.mod(pts, spacing)
        origins = np.unique(np.round(res, 3), axis=0)[:64]
        d = np.abs(res[None] - origins[:, None])
        d = np.minimum(d, spacing - d)
        hits = np.all(d < 1e-3, axis=2).sum(axis=1)
        k = int(np.argmax(hits))
        score = (int(hits[k]), spacing)
        if best is None or score > best[0]:
            best = (score, spacing, origins[k])
    assert best is not None
    return float(best[1]), np.asarray(best[2], dtype=float)


@dataclass
class Lattice:
    """Vertices (grid points on the levels in use, then off-grid endpoints) and their moves."""

    problem: SwarmProblem
    spacing_m: float
    levels_m: np.ndarray  # (L,) heights in use, m
    shape: tuple[int, int, int]  # (nx, ny, L)
    origin_m: np.ndarray  # (2,) xy of grid point (0, 0), m
    pos_m: np.ndarray  # (V, 3) vertex positions, m
    pos_mm: np.ndarray  # (V, 3) int64, whole millimetres
    free: np.ndarray  # (nx, ny, L) bool: grid point statically free
    start_v: np.ndarray  # (A,) vertex of each agent's start
    goal_v: np.ndarray  # (A,) vertex of each agent's goal
    access: dict[int, list[int]] = field(default_factory=dict)  # vertex -> access neighbours (both ways)
    max_run: int = 4
    dist_to_goal: np.ndarray | None = None  # (A, V) m, inf where unreachable
    _moves: dict[int, list[int]] = field(default_factory=dict)
    _edge_free: dict[tuple[int, int], bool] = field(default_factory=dict)

    @property
    def n_grid(self) -> int:
        return int(np.prod(self.shape))

    def grid_index(self, v: int) -> tuple[int, int, int] | None:
        if v >= self.n_grid:
            return None
        nx, ny, nl = self.shape
        ix, rest = divmod(v, ny * nl)
        iy, il = divmod(rest, nl)
        return ix, iy, il

    def vertex(self, ix: int, iy: int, il: int) -> int:
        _, ny, nl = self.shape
        return (ix * ny + iy) * nl + il

    def _unit_free(self, u: int, v: int) -> bool:
        key = (u, v) if u < v else (v, u)
        ok = self._edge_free.get(key)
        if ok is None:
            ok = self.problem.segment_free(self.pos_m[u], self.pos_m[v])
            self._edge_free[key] = ok
        return ok

    def unit_neighbours(self, v: int) -> list[int]:
        """Vertices one grid edge away (8 horizontal, adjacent levels) plus access neighbours."""
        out = list(self.access.get(v, ()))
        g = self.grid_index(v)
        if g is None:
            return out
        ix, iy, il = g
        nx, ny, nl = self.shape
        cand = [(ix + dx, iy + dy, il) for dx, dy in XY_DIRECTIONS] + [(ix, iy, il - 1), (ix, iy, il + 1)]
        for jx, jy, jl in cand:
            if 0 <= jx < nx and 0 <= jy < ny and 0 <= jl < nl and self.free[jx, jy, jl]:
                w = self.vertex(jx, jy, jl)
                if self._unit_free(v, w):
                    out.append(w)
        return out

    def moves(self, agent: int, v: int) -> list[int]:
        """Destinations of one step from ``v`` for ``agent`` (without staying), see module."""
        base = self._moves.get(v)
        if base is None:
            base = list(self.access.get(v, ()))
            g = self.grid_index(v)
            if g is not None:
                ix, iy, il = g
                nx, ny, nl = self.shape
                for dx, dy in XY_DIRECTIONS:
                    prev = v
                    for k in range(1, self.max_run + 1):
                        jx, jy = ix + k * dx, iy + k * dy
                        if not (0 <= jx < nx and 0 <= jy < ny and self.free[jx, jy, il]):
                            break
                        w = self.vertex(jx, jy, il)
                        if not self._unit_free(prev, w):
                            break
                        base.append(w)
                        prev = w
                for jl in range(nl):
                    if jl != il and self.free[ix, iy, jl]:
                        w = self.vertex(ix, iy, jl)
                        if self.problem.segment_free(self.pos_m[v], self.pos_m[w]):
                            base.append(w)
            self._moves[v] = base
        goal = int(self.goal_v[agent])
        if goal != v and goal not in base:
            reach = self.max_run * self.spacing_m * math.sqrt(2.0)
            if float(np.linalg.norm(self.pos_m[goal] - self.pos_m[v])) <= reach and self.problem.segment_free(
                self.pos_m[v], self.pos_m[goal]
            ):
                return base + [goal]
        return base

    def longest_move_m(self) -> float:
        """Upper bound of one move's length (runs, level changes, access, direct-to-goal), m."""
        span_z = float(self.levels_m[-1] - self.levels_m[0]) if len(self.levels_m) > 1 else 0.0
        return max(self.max_run * self.spacing_m * math.sqrt(2.0), ACCESS_RADIUS_FACTOR * self.spacing_m, span_z)


def build_lattice(problem: SwarmProblem, *, max_run: int = 4) -> Lattice:
    """The :class:`Lattice` of ``problem`` (see module), with ``dist_to_goal`` filled."""
    pts = np.vstack([problem.starts_m, problem.goals_m])
    levels = np.unique(np.round(pts[:, 2], 3))
    reach = problem.reach_xy_m
    spacing, residue = choose_spacing(pts, SPACING_RANGE[0] * reach, SPACING_RANGE[1] * reach)
    lo, hi = problem.lo_m, problem.hi_m
    first = lo[:2] + np.mod(residue - lo[:2], spacing)
    nx = max(1, int(math.floor((hi[0] - first[0]) / spacing + 1e-9)) + 1)
    ny = max(1, int(math.floor((hi[1] - first[1]) / spacing + 1e-9)) + 1)
    nl = len(levels)
    ix, iy, il = np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nl), indexing="ij")
    grid = np.stack([first[0] + ix * spacing, first[1] + iy * spacing, levels[il]], axis=-1)
    free = problem.static_free(grid)
    pos = grid.reshape(-1, 3)
    n_grid = pos.shape[0]
    ok_index = np.flatnonzero(free.reshape(-1))
    tree = cKDTree(pos[ok_index]) if ok_index.size else None
    extra: list[np.ndarray] = []
    access: dict[int, list[int]] = {}
    endpoint_v = []
    for p in pts:
        if tree is not None:
            dist, nn = tree.query(p, k=min(ACCESS_NEIGHBOURS, ok_index.size))
            dist, nn = np.atleast_1d(dist), np.atleast_1d(nn)
            if dist[0] < 1e-6:
                endpoint_v.append(int(ok_index[nn[0]]))
                continue
        same = [k for k, q in enumerate(extra) if float(np.linalg.norm(q - p)) < 1e-6]
        if same:
            endpoint_v.append(n_grid + same[0])
            continue
        vid = n_grid + len(extra)
        extra.append(np.asarray(p, dtype=float))
        links = []
        if tree is not None:
            for d, j in zip(dist, nn):
                w = int(ok_index[j])
                if d <= ACCESS_RADIUS_FACTOR * spacing and problem.segment_free(p, pos[w]):
                    links.append(w)
        access[vid] = links
        for w in links:
            access.setdefault(w, []).append(vid)
        endpoint_v.append(vid)
    if extra:
        pos = np.vstack([pos, np.array(extra)])
    A = problem.n_agents
    lat = Lattice(
        problem=problem,
        spacing_m=spacing,
        levels_m=levels,
        shape=(nx, ny, nl),
        origin_m=first,
        pos_m=pos,
        pos_mm=np.round(pos * 1000.0).astype(np.int64),
        free=free,
        start_v=np.array(endpoint_v[:A], dtype=np.int64),
        goal_v=np.array(endpoint_v[A:], dtype=np.int64),
        access=access,
        max_run=max_run,
    )
    lat.dist_to_goal = _distances(lat)
    return lat


def _distances(lat: Lattice) -> np.ndarray:
    """(A, V) metric shortest distance of every vertex to each agent's goal over unit edges, m."""
    V = lat.pos_m.shape[0]
    rows: list[int] = []
    cols: list[int] = []
    nx, ny, nl = lat.shape
    free = lat.free
    idx = np.arange(lat.n_grid).reshape(lat.shape)
    steps = [(dx, dy, 0) for dx, dy in XY_DIRECTIONS] + [(0, 0, 1), (0, 0, -1)]
    r_all, c_all = [], []
    for dx, dy, dl in steps:
        a = idx[max(0, -dx) : nx - max(0, dx), max(0, -dy) : ny - max(0, dy), max(0, -dl) : nl - max(0, dl)]
        b = idx[max(0, dx) : nx + min(0, dx), max(0, dy) : ny + min(0, dy), max(0, dl) : nl + min(0, dl)]
        fa = free.reshape(-1)[a.ravel()] & free.reshape(-1)[b.ravel()]
        r_all.append(a.ravel()[fa])
        c_all.append(b.ravel()[fa])
    r = np.concatenate(r_all) if r_all else np.zeros(0, np.int64)
    c = np.concatenate(c_all) if c_all else np.zeros(0, np.int64)
    # static check of the unit edges (midpoints and quarter points), vectorised
    ok = np.ones(r.size, dtype=bool)
    for s in (0.25, 0.5, 0.75):
        ok &= lat.problem.static_free(lat.pos_m[r] * (1 - s) + lat.pos_m[c] * s)
    r, c = r[ok], c[ok]
    for v, links in lat.access.items():
        for w in links:
            rows.append(v)
            cols.append(w)
    r = np.concatenate([r, np.array(rows, dtype=np.int64)])
    c = np.concatenate([c, np.array(cols, dtype=np.int64)])
    w = np.linalg.norm(lat.pos_m[r] - lat.pos_m[c], axis=1)
    graph = csr_matrix((w, (r, c)), shape=(V, V))
    goals, inv = np.unique(lat.goal_v, return_inverse=True)
    dist = dijkstra(graph, directed=True, indices=goals).astype(np.float32)
    # Dijkstra from the goal over directed edges u->v gives distance goal->v; the graph is symmetric
    return dist[inv]
