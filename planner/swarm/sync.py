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
a stencil, filled lazily).
"""

from __future__ import annotations

import math

import numpy as np

from proxplan.planner.swarm.keepout import KeepOut
from proxplan.planner.swarm.problem import GROWTH_M


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


class SyncTable:
    """Cached synchronous conflict test of two agents' moves on vertices with positions
    ``pos_mm`` (V, 3) integer millimetres (see module)."""

    def __init__(self, keepouts: dict[tuple[int, int], KeepOut], type_index: np.ndarray, pos_mm: np.ndarray):
        self.keepouts = keepouts
        self.types = [int(t) for t in type_index]
        self.pos = [tuple(int(c) for c in p) for p in np.asarray(pos_mm)]
        self.cache: dict[tuple, bool] = {}
        # the verdicts again by vertices (one int per (type pair, ui, vi, uj, vj)): a step asks the
        # same four vertices many times, and this key costs less to build and hash than the relative
        # one above (a memo of the same answers: the plans are the same)
        self.by_vertices: dict[int, bool] = {}
        self._n_vertices = len(self.pos)
        self._n_types = max(self.types, default=0) + 1
        self.computed = 0  # exact tests run (cache misses)
        self.far = 0  # of those, settled by the horizontal reach alone (far_apart)
        # per (type pair, both at rest): the largest horizontal distance at which the keep-out holds a
        # point, grown as segment_conflict grows it (GROWTH_M at rest), m
        self.reach_m = {
            (pair, rest): ko.horizontal_reach_m(rest=rest) + (GROWTH_M if rest else 0.0)
            for pair, ko in keepouts.items()
            for rest in (False, True)
        }

    def conflict(self, i: int, ui: int, vi: int, j: int, uj: int, vj: int) -> bool:
        """Do agent i moving ui -> vi and agent j moving uj -> vj in one step conflict?"""
        V = self._n_vertices
        vkey = ((((self.types[i] * self._n_types + self.types[j]) * V + ui) * V + vi) * V + uj) * V + vj
        hit = self.by_vertices.get(vkey)
        if hit is None:
            hit = self.by_vertices[vkey] = self._relative(i, ui, vi, j, uj, vj)
        return hit

    def _relative(self, i: int, ui: int, vi: int, j: int, uj: int, vj: int) -> bool:
        """:meth:`conflict` by the relative motion (cached per type pair, d0, d1)."""
        P = self.pos
        pu_i, pv_i, pu_j, pv_j = P[ui], P[vi], P[uj], P[vj]
        key = (
            self.types[i],
            self.types[j],
            pu_j[0] - pu_i[0],
            pu_j[1] - pu_i[1],
            pu_j[2] - pu_i[2],
            pv_j[0] - pv_i[0],
            pv_j[1] - pv_i[1],
            pv_j[2] - pv_i[2],
            ui == vi and uj == vj,
        )
        hit = self.cache.get(key)
        if hit is None:
            self.computed += 1
            if far_apart(key[2:8], self.reach_m[((key[0], key[1]), key[8])]):
                self.far += 1
                self.cache[key] = False
                return False
            d0 = np.array(key[2:5], dtype=float) * 1e-3
            d1 = np.array(key[5:8], dtype=float) * 1e-3
            hit = segment_conflict(
                self.keepouts[(key[0], key[1])], d0, d1, rest=bool(key[8]), growth_m=GROWTH_M if key[8] else 0.0
            )
            self.cache[key] = hit
        return hit
