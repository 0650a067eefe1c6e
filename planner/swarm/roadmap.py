"""A roadmap shared by every vehicle of a swarm: a 3-D lattice aligned with starts and goals, plus
access edges from each start / goal to nearby lattice vertices, and its conflict sets.

World frame, z up, m. The lattice has spacing ``spacing_m = (l_xy, l_xy, l_z)``; ``l_xy`` is the
largest horizontal reach of any pair's keep-out (separation and cut-off radius r_cut(dz), each
plus the tracking tube and the sampling inflation), so horizontally neighbouring vertices never
conflict and the conflict sets stay sparse; ``l_z`` is the smallest vertical gap between start /
goal levels (>= the separation keep-out). Among candidate spacings / origins the one that puts most
starts and goals exactly on vertices wins (the others reach the lattice over access edges).

**Atoms.** What a vehicle occupies during one time window of the search is a set of *atoms*:
lattice vertices (kind 0), unit lattice edges along ``DIRECTIONS`` (x, y, z and the two horizontal
diagonals; kinds 1..5, indexed by the vertex they leave in the + direction), start / goal points
("endpoints") and access edges. Atom ids: ``kind * V + flat vertex index`` for the lattice
(V = nx ny nz), then endpoints, then access edges.

**Conflict sets.** Two atoms conflict for vehicle types (a, b) when some point of one and some
point of the other are closer than the pair's keep-out (:mod:`proxplan.planner.swarm.keepout`),
whatever the timing within the window (swept volumes): this holds for any motion that stays on its
atoms during the window, which is how the runs of :mod:`proxplan.planner.swarm.search` are flown.
The lattice is translation invariant, so lattice-lattice conflicts are a *stencil* of index offsets
per (type pair, atom kind pair), computed once with a vectorised point test and expanded to a
``scipy.sparse`` CSR matrix per ordered type pair; endpoint / access atoms are tested against
candidates found with a ``scipy.spatial.cKDTree``. Endpoint-endpoint pairs (both vehicles at rest)
leave the tracking tube out, as the verifier does for pairs at rest.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from proxplan.planner.swarm.keepout import KeepOut

DIRECTIONS = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0], [1, -1, 0]])  # edge kinds 1.., index steps
SAMPLE_M = 0.05  # point spacing on edges for the conflict test, m (keep-outs are grown by it)
ACCESS_NEIGHBOURS = 6  # lattice vertices each start / goal connects to
ACCESS_RADIUS_FACTOR = 1.8  # ... within this many horizontal spacings


@dataclass
class Roadmap:
    """Lattice, endpoints, access edges, static validity and conflict sets (see module)."""

    origin_m: np.ndarray  # (3,) position of vertex (0, 0, 0), m
    spacing_m: np.ndarray  # (3,) m
    shape: tuple[int, int, int]
    vertex_ok: np.ndarray  # (nx, ny, nz) bool: vertex free of workspace bounds / obstacles
    edge_ok: np.ndarray  # (K, nx, ny, nz) bool: unit edge from the vertex along +DIRECTIONS[k] is free
    endpoints_m: np.ndarray  # (E, 3) start / goal points, m
    endpoint_vertex: np.ndarray  # (E,) flat lattice vertex the endpoint coincides with, or -1
    access: list[tuple[int, int]]  # (endpoint, flat lattice vertex) per access edge
    type_names: tuple[str, ...]
    conflicts: dict[tuple[int, int], sp.csr_matrix] = field(default_factory=dict)  # (type a, type b)

    @property
    def n_vertices(self) -> int:
        return int(np.prod(self.shape))

    @property
    def n_lattice_atoms(self) -> int:
        return (1 + len(DIRECTIONS)) * self.n_vertices

    def endpoint_atom(self, e: int) -> int:
        """The atom of endpoint ``e`` held at rest (its own atom even on a lattice vertex, so that
        two resting vehicles are checked without the tracking tube)."""
        return self.n_lattice_atoms + e

    def access_atom(self, k: int) -> int:
        return self.n_lattice_atoms + len(self.endpoints_m) + k

    @property
    def n_atoms(self) -> int:
        return self.n_lattice_atoms + len(self.endpoints_m) + len(self.access)

    def position(self, flat: int) -> np.ndarray:
        idx = np.array(np.unravel_index(flat, self.shape))
        return self.origin_m + idx * self.spacing_m

    def atom_points(self, atom: int) -> np.ndarray:
        """Sample points (P, 3) of one atom, m (every SAMPLE_M along edges, both ends included)."""
        n_lat = self.n_lattice_atoms
        if atom < n_lat:
            kind, flat = divmod(atom, self.n_vertices)
            p0 = self.position(flat)
            if kind == 0:
                return p0[None]
            return _segment_points(p0, p0 + DIRECTIONS[kind - 1] * self.spacing_m)
        e = atom - n_lat
        if e < len(self.endpoints_m):
            return self.endpoints_m[e][None]
        k = e - len(self.endpoints_m)
        end, v = self.access[k]
        return _segment_points(self.endpoints_m[end], self.position(v))

    def blocked_by(self, type_a: int, type_b: int, atoms: np.ndarray) -> np.ndarray:
        """Atoms a vehicle of ``type_b`` may not occupy while one of ``type_a`` occupies ``atoms``
        in the same window (with repeats)."""
        c = self.conflicts[(type_a, type_b)]
        atoms = np.asarray(atoms, dtype=np.int64)
        start, stop = c.indptr[atoms], c.indptr[atoms + 1]
        lens = stop - start
        if lens.sum() == 0:
            return np.zeros(0, dtype=np.int64)
        idx = np.repeat(start - np.cumsum(np.r_[0, lens[:-1]]), lens) + np.arange(lens.sum())
        return c.indices[idx].astype(np.int64)


def _segment_points(p0: np.ndarray, p1: np.ndarray) -> np.ndarray:
    n = max(2, int(math.ceil(float(np.linalg.norm(p1 - p0)) / SAMPLE_M)) + 1)
    s = np.linspace(0.0, 1.0, n)[:, None]
    return p0[None] * (1.0 - s) + p1[None] * s


def _static_free(points: np.ndarray, lo: np.ndarray, hi: np.ndarray, boxes: np.ndarray) -> np.ndarray:
    """(P,) bool: point inside the (body-shrunk) workspace and outside every inflated obstacle."""
    ok = np.all((points >= lo) & (points <= hi), axis=-1)
    for b in boxes:
        inside = np.all((points >= b[:3]) & (points <= b[3:]), axis=-1)
        ok &= ~inside
    return ok


def choose_lattice(
    points_m: np.ndarray, lo_m: np.ndarray, hi_m: np.ndarray, min_xy_m: float, min_z_m: float
) -> tuple[np.ndarray, np.ndarray, tuple[int, int, int]]:
    """(origin, spacing, shape) of the lattice: spacing >= the minimum keep-out spacings (m), among
    a few candidates the one (and its origin) putting most of ``points_m`` (starts / goals) on
    vertices; ties go to the smaller spacing."""
    pts = np.asarray(points_m, dtype=float)
    z_levels = np.unique(np.round(pts[:, 2], 3))
    gaps = np.diff(z_levels)
    gaps = gaps[gaps >= min_z_m - 1e-9]
    l_z = float(gaps.min()) if gaps.size else max(min_z_m, 0.5)
    l_z = min(max(l_z, min_z_m), 1.0)
    best = None
    cands = set(np.round(np.arange(min_xy_m, 2.0 * min_xy_m + 1e-9, 0.05), 4).tolist())
    for axis in (0, 1):  # multiples and fractions of the gaps between the points' coordinates
        gaps = np.unique(np.round(np.diff(np.unique(np.round(pts[:, axis], 3))), 3))
        for g in gaps[gaps > 0][:8]:
            for k in range(1, 9):
                for f in (g * k, g / k):
                    if min_xy_m <= f <= 2.0 * min_xy_m:
                        cands.add(round(float(f), 4))
    for l_xy in sorted(cands):
        l_xy = float(max(l_xy, min_xy_m))
        spacing = np.array([l_xy, l_xy, l_z])
        # candidate origins: the residues of the points themselves; score = points on vertices
        res = np.mod(pts, spacing)
        cand = np.unique(np.round(res, 3), axis=0)[:64]
        d = np.abs(res[None, :, :] - cand[:, None, :])
        d = np.minimum(d, spacing - d)
        hits = np.all(d < 1e-3, axis=2).sum(axis=1)
        k = int(np.argmax(hits))
        score = (int(hits[k]), -l_xy)
        if best is None or score > best[0]:
            best = (score, cand[k], spacing)
    assert best is not None
    _, residue, spacing = best
    first = lo_m + np.mod(residue - lo_m, spacing)  # first lattice coordinate >= lo on each axis
    shape = tuple(int(math.floor((hi_m[a] - first[a]) / spacing[a] + 1e-9)) + 1 for a in range(3))
    return first, spacing, (max(shape[0], 1), max(shape[1], 1), max(shape[2], 1))


def build_roadmap(
    endpoints_m: np.ndarray,
    lo_m: np.ndarray,
    hi_m: np.ndarray,
    boxes: np.ndarray,
    keepouts: dict[tuple[int, int], KeepOut],
    type_names: tuple[str, ...],
) -> Roadmap:
    """The roadmap for ``endpoints_m`` (E, 3) (starts and goals, m) inside [lo, hi] (workspace
    already shrunk by the body and tube margins) avoiding ``boxes`` (O, 6) (inflated obstacles),
    with conflict sets for every ordered pair of the types in ``keepouts``."""
    min_xy = max(k.reach_xy_m for k in keepouts.values()) + 1e-3
    min_z = max(k.separation_m for k in keepouts.values()) + 1e-3
    origin, spacing, shape = choose_lattice(endpoints_m, lo_m, hi_m, min_xy, min_z)
    grid = np.stack(np.meshgrid(*[np.arange(n) for n in shape], indexing="ij"), axis=-1)
    pos = origin + grid * spacing  # (nx, ny, nz, 3)
    vertex_ok = _static_free(pos, lo_m, hi_m, boxes)
    edge_ok = np.zeros((len(DIRECTIONS),) + shape, dtype=bool)
    for kind, step_idx in enumerate(DIRECTIONS):
        step = step_idx * spacing
        n_s = max(2, int(math.ceil(float(np.linalg.norm(step)) / SAMPLE_M)) + 1)
        ok = vertex_ok.copy()
        for s in np.linspace(0.0, 1.0, n_s):
            ok &= _static_free(pos + s * step, lo_m, hi_m, boxes)
        end = grid + step_idx
        inside = np.all((end >= 0) & (end < np.array(shape)), axis=-1)
        ok &= inside
        end_ok = np.zeros(shape, dtype=bool)
        end_ok[inside] = vertex_ok[tuple(end[inside].T)]
        edge_ok[kind] = ok & end_ok
    flat_pos = pos.reshape(-1, 3)
    tree = cKDTree(flat_pos[vertex_ok.reshape(-1)])
    ok_index = np.flatnonzero(vertex_ok.reshape(-1))
    ep = np.asarray(endpoints_m, dtype=float)
    endpoint_vertex = np.full(len(ep), -1, dtype=np.int64)
    access: list[tuple[int, int]] = []
    if ok_index.size:
        dist, nn = tree.query(ep, k=min(ACCESS_NEIGHBOURS, ok_index.size))
        dist, nn = np.atleast_2d(dist), np.atleast_2d(nn)
        for e in range(len(ep)):
            if dist[e, 0] < 1e-6:
                endpoint_vertex[e] = ok_index[nn[e, 0]]
                continue
            for d, j in zip(dist[e], nn[e], strict=True):
                if d > ACCESS_RADIUS_FACTOR * spacing[0]:
                    continue
                v = int(ok_index[j])
                if _static_free(_segment_points(ep[e], flat_pos[v]), lo_m, hi_m, boxes).all():
                    access.append((e, v))
    rm = Roadmap(origin, spacing, shape, vertex_ok, edge_ok, ep, endpoint_vertex, access, type_names)
    _conflict_sets(rm, keepouts)
    return rm


def _lattice_kind_points(spacing: np.ndarray) -> list[np.ndarray]:
    """Sample points of the lattice atom kinds at vertex (0, 0, 0), relative, m."""
    out = [np.zeros((1, 3))]
    for step in DIRECTIONS:
        out.append(_segment_points(np.zeros(3), step * spacing))
    return out


def _stencil(keep: KeepOut, spacing: np.ndarray) -> dict[tuple[int, int], np.ndarray]:
    """For atom kinds (ka, kb): the index offsets (n, 3) at which an atom of kind kb (vehicle type
    b) conflicts with one of kind ka at the origin (type a)."""
    pts = _lattice_kind_points(spacing)
    reach = np.array([keep.reach_xy_m, keep.reach_xy_m, keep.reach_z_m])
    span = np.ceil(reach / spacing).astype(int) + 2
    off = np.stack(np.meshgrid(*[np.arange(-s, s + 1) for s in span], indexing="ij"), axis=-1).reshape(-1, 3)
    out = {}
    n_kinds = 1 + len(DIRECTIONS)
    for ka in range(n_kinds):
        for kb in range(n_kinds):
            pa, pb = pts[ka], pts[kb]
            # horizontal gap between the two atoms' boxes: beyond the reach no test is needed
            lo_b = off[:, :2] * spacing[:2] + pb[:, :2].min(axis=0)
            hi_b = off[:, :2] * spacing[:2] + pb[:, :2].max(axis=0)
            gap = np.maximum(0.0, np.maximum(lo_b - pa[:, :2].max(axis=0), pa[:, :2].min(axis=0) - hi_b))
            near = np.hypot(gap[:, 0], gap[:, 1]) < keep.reach_xy_m
            o = off[near]
            # relative vectors: (offset, point of b, point of a)
            d = (o * spacing)[:, None, None, :] + pb[None, :, None, :] - pa[None, None, :, :]
            hit = keep.conflict(d.reshape(-1, 3)).reshape(d.shape[:3]).any(axis=(1, 2))
            out[(ka, kb)] = o[hit]
    return out


def _points_of(rm: Roadmap, atoms: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sample points (P, 3), m, of ``atoms`` and the atom of each point (P,)."""
    pts, own = [], []
    for a in atoms.tolist():
        p = rm.atom_points(int(a))
        pts.append(p)
        own.append(np.full(len(p), a, dtype=np.int64))
    if not pts:
        return np.zeros((0, 3)), np.zeros(0, dtype=np.int64)
    return np.concatenate(pts), np.concatenate(own)


def _lattice_points(rm: Roadmap, atom_ok: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sample points and owning atoms of every valid lattice atom (vectorised)."""
    nv = rm.n_vertices
    idx = np.stack(np.unravel_index(np.arange(nv), rm.shape), axis=-1)
    base = rm.origin_m + idx * rm.spacing_m
    pts, own = [], []
    for kind, rel in enumerate(_lattice_kind_points(rm.spacing_m)):
        ok = np.flatnonzero(atom_ok[kind * nv : (kind + 1) * nv])
        p = base[ok][:, None, :] + rel[None, :, :]
        pts.append(p.reshape(-1, 3))
        own.append(np.repeat(kind * nv + ok, len(rel)))
    return np.concatenate(pts), np.concatenate(own)


def _conflict_sets(rm: Roadmap, keepouts: dict[tuple[int, int], KeepOut]) -> None:
    """Fill ``rm.conflicts`` (see module): stencils for lattice pairs, point tests for the rest."""
    shape = np.array(rm.shape)
    nv = rm.n_vertices
    n_atoms = rm.n_atoms
    idx = np.stack(np.unravel_index(np.arange(nv), rm.shape), axis=-1)  # (V, 3)
    atom_ok = np.concatenate([rm.vertex_ok.reshape(-1)] + [e.reshape(-1) for e in rm.edge_ok])
    extra = np.arange(rm.n_lattice_atoms, n_atoms)
    ex_pts, ex_own = _points_of(rm, extra)
    lat_pts, lat_own = _lattice_points(rm, atom_ok)
    reach = max(k.reach_xy_m for k in keepouts.values()) + 1e-6
    n_end = len(rm.endpoints_m)
    # candidate point pairs by horizontal distance (the vertical reach spans the whole lattice)
    ex_tree = cKDTree(ex_pts[:, :2]) if len(ex_pts) else None
    el = ex_tree.sparse_distance_matrix(cKDTree(lat_pts[:, :2]), reach, output_type="ndarray") if ex_tree else None
    ee = ex_tree.sparse_distance_matrix(ex_tree, reach, output_type="ndarray") if ex_tree else None
    for (ta, tb), keep in keepouts.items():
        rows, cols = [], []
        for (ka, kb), offs in _stencil(keep, rm.spacing_m).items():
            src = np.flatnonzero(atom_ok[ka * nv : (ka + 1) * nv])
            if src.size == 0 or offs.size == 0:
                continue
            tgt = idx[src][:, None, :] + offs[None, :, :]  # (S, O, 3)
            inside = np.all((tgt >= 0) & (tgt < shape), axis=-1)
            s_i, o_i = np.nonzero(inside)
            flat_t = np.ravel_multi_index(tuple(tgt[s_i, o_i].T), rm.shape)
            t_atom = kb * nv + flat_t
            keep_mask = atom_ok[t_atom]
            rows.append(ka * nv + src[s_i[keep_mask]])
            cols.append(t_atom[keep_mask])
        if el is not None and el.size:
            i, j = el["i"], el["j"]
            d = lat_pts[j] - ex_pts[i]  # lattice (type tb) relative to irregular (type ta)
            hit = keep.conflict(d)
            rows.append(ex_own[i[hit]])
            cols.append(lat_own[j[hit]])
            hit2 = keep.conflict(-d)  # irregular (type tb) relative to lattice (type ta)
            rows.append(lat_own[j[hit2]])
            cols.append(ex_own[i[hit2]])
        if ee is not None and ee.size:
            i, j = ee["i"], ee["j"]
            d = ex_pts[j] - ex_pts[i]
            a_i, a_j = ex_own[i], ex_own[j]
            rest = ((a_i - rm.n_lattice_atoms) < n_end) & ((a_j - rm.n_lattice_atoms) < n_end)
            hit = np.where(rest, keep.conflict(d, rest=True), keep.conflict(d))
            rows.append(a_i[hit])
            cols.append(a_j[hit])
        r = np.concatenate(rows) if rows else np.zeros(0, dtype=np.int64)
        c = np.concatenate(cols) if cols else np.zeros(0, dtype=np.int64)
        mat = sp.csr_matrix((np.ones(r.size, dtype=bool), (r, c)), shape=(n_atoms, n_atoms))
        mat.sum_duplicates()
        mat.sort_indices()
        rm.conflicts[(ta, tb)] = mat
