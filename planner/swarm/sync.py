"""Synchronous conflicts of two moves, checked exactly and tabulated once per relative motion.

Two vehicles i and j that move in the same step of a coordination plan, i from u_i to v_i and j
from u_j to v_j (straight lines, both started together and flown with one normalised profile
s(t) in [0, 1], :mod:`proxplan.planner.swarm.lockstep`), have the relative position
d(s) = (u_j - u_i) + s ((v_j - u_j) - (v_i - u_i)): a straight segment from d0 = u_j - u_i to
d1 = v_j - v_i. The step is in conflict when that segment enters the pair's keep-out
(:class:`proxplan.planner.swarm.keepout.KeepOut`; moving keep-out, with the tracking tube, unless
both vehicles stay put). Following (j moving into the place i leaves, in the same direction) keeps
d constant and is allowed; side-by-side crossings and head-on swaps sweep d through the keep-out
and are rejected. This is exact for the relative motion, unlike swept-volume conflict sets.

:func:`segment_conflict` is the exact test: the keep-out is a sphere of radius separation + w
union vertical columns whose radius is piecewise constant in dz (the cut-off tables, one value
per dz band); the segment is split where its dz crosses a band edge, and on each piece the smallest
horizontal distance (a quadratic in s) is compared with that piece's radius. :class:`SyncTable`
caches the verdict per (type pair, d0, d1) with positions in whole millimetres, so every
lattice translation of a relative motion is computed once (the same translation-invariant trick as
a stencil, filled lazily), under one int key and up to a stated count (``MAX_VERDICTS``).
"""

from __future__ import annotations

import math
from itertools import islice

import numpy as np

from proxplan.planner.swarm.keepout import KeepOut
from proxplan.planner.swarm.problem import GROWTH_M

# verdicts a SyncTable keeps, at most: each costs about 90 bytes (an int key of 4-5 30-bit digits,
# 40-48 bytes, and its dict slot; 2^22 random keys measured: 353 MB, 88 B each), so the table stays
# below about 400 MB (550 MB while the newer half is copied out), a tenth of the 4 GB that issue 37
# allows a 256-vehicle plan (the table's only purpose is speed: a verdict dropped is computed again,
# exactly)
MAX_VERDICTS = 1 << 22
# relative margin of maybe_near's conservative test over far_apart's (float rounding of a vectorised
# quadratic on positions of a few metres: about 1e-15 relative; 1e-6 is far from both the rounding
# and any verdict's margin, and a pair kept by it is only tested exactly, never decided by it)
NEAR_MARGIN = 1e-6


def _column_radius(ko: KeepOut, dz: float, rest: bool) -> float:
    """Column radius of the keep-out at relative height dz (KeepOut.conflict's rule), m."""
    below, above = (ko.a_on_b_rest, ko.b_on_a_rest) if rest else (ko.a_on_b, ko.b_on_a)
    w = ko.w_rest_m if rest else ko.w_move_m
    k = int(math.floor(abs(dz) / ko.step_m))
    rb = float(below[k]) if k < below.size else 0.0
    ra = float(above[k]) if k < above.size else 0.0
    if abs(dz) <= w + 1e-12:
        return max(rb, ra)
    return rb if dz < 0 else (ra if dz > 0 else 0.0)


def _min_r2(d0: np.ndarray, e: np.ndarray, s0: float, s1: float) -> float:
    """Smallest horizontal |d0 + s e|^2 over s in [s0, s1], m^2."""
    a = float(e[0] * e[0] + e[1] * e[1])
    b = float(d0[0] * e[0] + d0[1] * e[1])
    s = s0 if a <= 0.0 else min(max(-b / a, s0), s1)
    x, y = d0[0] + s * e[0], d0[1] + s * e[1]
    return float(x * x + y * y)


def segment_conflict(ko: KeepOut, d0_m: np.ndarray, d1_m: np.ndarray, *, rest: bool, growth_m: float = 0.0) -> bool:
    """Does the relative segment d0 -> d1 (m, d = p_b - p_a) enter the keep-out of ``ko``
    (grown by ``growth_m``)? ``rest``: both vehicles stay put (the keep-out without the tube)."""
    d0 = np.asarray(d0_m, dtype=float)
    e = np.asarray(d1_m, dtype=float) - d0
    w = ko.w_rest_m if rest else ko.w_move_m
    sep = ko.separation_m + w + growth_m
    ee = float(e @ e)
    s = 0.0 if ee <= 0.0 else min(max(-float(d0 @ e) / ee, 0.0), 1.0)
    p = d0 + s * e
    if float(p @ p) < sep * sep:
        return True
    # columns: split [0, 1] where dz crosses a band edge, the tube band or zero
    z0, ez = float(d0[2]), float(e[2])
    cuts = [0.0, 1.0]
    if ez != 0.0:
        z_lo, z_hi = min(z0, z0 + ez), max(z0, z0 + ez)
        step = ko.step_m
        edges = [k * step for k in range(int(math.floor(z_lo / step)), int(math.floor(z_hi / step)) + 2)]
        edges += [-w, w, 0.0]
        for zc in edges:
            for sign in (1.0, -1.0):
                sc = (sign * zc - z0) / ez
                if 0.0 < sc < 1.0:
                    cuts.append(sc)
    cuts = sorted(set(cuts))
    for sa, sb in zip(cuts[:-1], cuts[1:]):
        for sm in ((sa + sb) / 2.0, sa, sb):  # the piece's interior value and its closed ends
            rc = _column_radius(ko, z0 + sm * ez, rest)
            if rc <= 0.0:
                continue
            lo, hi = (sa, sb) if sm == (sa + sb) / 2.0 else (sm, sm)
            r = rc + growth_m
            if _min_r2(d0, e, lo, hi) < r * r:
                return True
    return False


def far_apart(d_mm: tuple[int, ...], reach_m: float) -> bool:
    """Does the relative segment d0 -> d1 (``d_mm`` = d0 then d1, whole mm) stay horizontally at least
    ``reach_m`` (its keep-out's horizontal reach, grown) from the origin? Then it cannot conflict:
    :func:`segment_conflict` needs a point of it horizontally closer than the sphere's radius or a
    column's (each at most the reach). Plain floats: the same quadratic as ``_min_r2`` on [0, 1]; a
    relative margin of 1e-9 keeps rounding on the side of the exact test."""
    x0, y0 = d_mm[0] * 1e-3, d_mm[1] * 1e-3
    ex, ey = d_mm[3] * 1e-3 - x0, d_mm[4] * 1e-3 - y0
    a = ex * ex + ey * ey
    s = 0.0 if a <= 0.0 else min(max(-(x0 * ex + y0 * ey) / a, 0.0), 1.0)
    x, y = x0 + s * ex, y0 + s * ey
    return x * x + y * y > reach_m * reach_m * (1.0 + 1e-9) + 1e-12


def maybe_near(d0_m: np.ndarray, d1_m: np.ndarray, reach_m: np.ndarray) -> np.ndarray:
    """Vectorised, conservative :func:`far_apart`: False only where the relative segments d0 -> d1
    (horizontal parts, m, arrays of shape (..., 2) that broadcast) stay horizontally clearly beyond
    ``reach_m`` (broadcasting with their leading shape) of the origin, so :func:`far_apart` holds there
    and the pair cannot conflict; True where they may come within reach. The margin (a relative 1e-6
    over far_apart's 1e-9, positions from whole mm) keeps float rounding on the side of the exact test."""
    e = d1_m - d0_m
    a = (e * e).sum(axis=-1)
    b = (d0_m * e).sum(axis=-1)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(a > 0.0, np.clip(-b / np.where(a > 0.0, a, 1.0), 0.0, 1.0), 0.0)
    p = d0_m + s[..., None] * e
    return (p * p).sum(axis=-1) <= reach_m * reach_m * (1.0 + NEAR_MARGIN) + 1e-9


class SyncTable:
    """Cached synchronous conflict test of two agents' moves on vertices with positions
    ``pos_mm`` (V, 3) integer millimetres (see module).

    The verdicts are kept by relative motion, one Python int per (type pair, d0, d1, both at rest)
    (:meth:`_key`), at most ``max_verdicts`` of them (the older half dropped when full: a verdict
    dropped is computed again, exactly, so the bound changes the time, never an answer)."""

    def __init__(
        self,
        keepouts: dict[tuple[int, int], KeepOut],
        type_index: np.ndarray,
        pos_mm: np.ndarray,
        *,
        max_verdicts: int = MAX_VERDICTS,
    ):
        self.keepouts = keepouts
        self.types = [int(t) for t in type_index]
        pos = np.asarray(pos_mm, dtype=np.int64).reshape(-1, 3)
        self.pos = [tuple(int(c) for c in p) for p in pos]
        self.max_verdicts = int(max_verdicts)
        self.verdicts: dict[int, bool] = {}
        # a vertex's position as one int in base B > 2 x the largest span of a coordinate, digits x, y, z:
        # the difference of two is the difference vector in balanced base B (each digit below B / 2 in
        # size), so it names that vector alone; two differences d0, d1 (each below B^3 / 2 in size)
        # combine into d0 B^3 + d1, as unique
        span = int((pos.max(axis=0) - pos.min(axis=0)).max()) if len(pos) else 0
        base = 1 << (2 * span + 1).bit_length()
        self._packed = [(x * base + y) * base + z for x, y, z in self.pos]
        self._cube = base**3
        self._n_types = max(self.types, default=0) + 1
        self.computed = 0  # exact tests run (verdicts not in the table: new, or dropped by the bound)
        self.far = 0  # of those, settled by the horizontal reach alone (far_apart)
        self.dropped = 0  # verdicts dropped by the bound
        # per (type pair, both at rest): the largest horizontal distance at which the keep-out holds a
        # point, grown as segment_conflict grows it (GROWTH_M at rest), m
        self.reach_m = {
            (pair, rest): ko.horizontal_reach_m(rest=rest) + (GROWTH_M if rest else 0.0)
            for pair, ko in keepouts.items()
            for rest in (False, True)
        }
        # per type pair (nt, nt): the larger of the two reaches above (moving, at rest), m: a pair
        # whose relative segment stays beyond it cannot conflict, whether or not both stay
        nt = max([self._n_types] + [max(pair) + 1 for pair in keepouts])
        self.reach_any_m = np.zeros((nt, nt))
        for (pair, _rest), r in self.reach_m.items():
            self.reach_any_m[pair] = max(self.reach_any_m[pair], r)

    def __len__(self) -> int:
        return len(self.verdicts)

    def clear(self) -> None:
        """Drop every verdict kept (the memory is freed now, whatever still refers to the table)."""
        self.verdicts = {}

    def _key(self, i: int, ui: int, vi: int, j: int, uj: int, vj: int) -> int:
        """One int per (type of i, type of j, d0 = p(uj) - p(ui), d1 = p(vj) - p(vi), both at rest)."""
        P, nt = self._packed, self._n_types
        rel = (P[uj] - P[ui]) * self._cube + (P[vj] - P[vi])
        return ((rel * nt + self.types[i]) * nt + self.types[j]) * 2 + (ui == vi and uj == vj)

    def conflict(self, i: int, ui: int, vi: int, j: int, uj: int, vj: int) -> bool:
        """Do agent i moving ui -> vi and agent j moving uj -> vj in one step conflict?"""
        key = self._key(i, ui, vi, j, uj, vj)
        hit = self.verdicts.get(key)
        if hit is None:
            hit = self._exact(i, ui, vi, j, uj, vj)
            if len(self.verdicts) >= self.max_verdicts:
                self._drop_older_half()
            self.verdicts[key] = hit
        return hit

    def _drop_older_half(self) -> None:
        """Keep the newer half of the verdicts (dicts keep insertion order): O(n) once per n / 2 insertions."""
        keep = len(self.verdicts) // 2
        self.dropped += len(self.verdicts) - keep
        self.verdicts = dict(islice(self.verdicts.items(), len(self.verdicts) - keep, None))

    def _exact(self, i: int, ui: int, vi: int, j: int, uj: int, vj: int) -> bool:
        """:meth:`conflict` computed: the relative segment against the type pair's keep-out."""
        self.computed += 1
        P = self.pos
        pu_i, pv_i, pu_j, pv_j = P[ui], P[vi], P[uj], P[vj]
        d_mm = tuple(pu_j[k] - pu_i[k] for k in range(3)) + tuple(pv_j[k] - pv_i[k] for k in range(3))
        pair, rest = (self.types[i], self.types[j]), ui == vi and uj == vj
        if far_apart(d_mm, self.reach_m[(pair, rest)]):
            self.far += 1
            return False
        d0 = np.array(d_mm[:3], dtype=float) * 1e-3
        d1 = np.array(d_mm[3:], dtype=float) * 1e-3
        return segment_conflict(self.keepouts[pair], d0, d1, rest=rest, growth_m=GROWTH_M if rest else 0.0)
