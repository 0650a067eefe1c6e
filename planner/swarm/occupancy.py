"""What the other vehicles forbid one vehicle: departure times of a straight move, hold times of a
point, on the swarm's time grid, against every other vehicle's :class:`~proxplan.planner.swarm.tracks.Track`.

The other tracks live in a horizontal spatial hash (cells of at least twice the largest reach), so
a query looks only at tracks whose bounding box comes within reach of the move: the space-time
neighbourhood, not every planned vehicle. For a move flown along a rest-to-rest profile whose
sample k is at q_k (k = 0..K), departing at grid step d puts the vehicle at q_k at step d + k; a
sample pair (track j at step t, move sample k) that violates the pair's keep-out forbids the single
departure d = t - k. Only (t, k) pairs that are horizontally within reach are tested (the samples k
whose distance along the move is within the reach of j's position at t, from a quadratic), so the
cost grows with how long others are near the move, not with the horizon. A parked track (after its
end) forbids a whole range of departures at once. Tests use the moving keep-out (the vehicle
moves); holds use the resting keep-out where the other vehicle rests too, as the verifier does.
Samples are ``GRID_DT_S`` apart; the keep-outs are grown for that (the chord between two samples of
a relative motion of at most 2 v_max GRID_DT_S stays outside a keep-out grown by
:data:`SAMPLING_GROWTH_M`).
"""

from __future__ import annotations

import math

import numpy as np

from proxplan.planner.swarm.problem import SwarmProblem
from proxplan.planner.swarm.tracks import Track

SAMPLING_GROWTH_M = 0.005  # keep-out growth covering motion between grid samples, m


class Occupancy:
    """The tracks of every vehicle of ``problem`` but the one being (re)planned (see module)."""

    def __init__(self, problem: SwarmProblem, tracks: list[Track], horizon_steps: int):
        self.problem = problem
        self.horizon = int(horizon_steps)
        self.reach = problem.reach_xy_m + SAMPLING_GROWTH_M
        self.cell = max(1.0, 2.0 * self.reach)
        self.tracks: dict[int, Track] = {}
        self.waiting: dict[int, tuple[np.ndarray, int]] = {}  # agent -> (start, until step): not planned yet
        self._cells: dict[tuple[int, int], set[int]] = {}
        self._cells_of: dict[int, list[tuple[int, int]]] = {}
        for tr in tracks:
            self.put(tr)

    def _span(self, lo: np.ndarray, hi: np.ndarray, pad: float) -> list[tuple[int, int]]:
        c = self.cell
        xs = range(int(math.floor((lo[0] - pad) / c)), int(math.floor((hi[0] + pad) / c)) + 1)
        ys = range(int(math.floor((lo[1] - pad) / c)), int(math.floor((hi[1] + pad) / c)) + 1)
        return [(x, y) for x in xs for y in ys]

    def put(self, track: Track) -> None:
        """Add ``track`` (replacing that agent's previous one)."""
        self.remove(track.agent)
        self.tracks[track.agent] = track
        cells = self._span(track.lo_m, track.hi_m, 0.0)
        self._cells_of[track.agent] = cells
        for c in cells:
            self._cells.setdefault(c, set()).add(track.agent)

    def remove(self, agent: int) -> Track | None:
        old = self.tracks.pop(agent, None)
        for c in self._cells_of.pop(agent, []):
            self._cells[c].discard(agent)
        return old

    def near(self, lo: np.ndarray, hi: np.ndarray, exclude: int) -> list[Track]:
        """Tracks whose bounding box comes within reach of the box [lo, hi] (m)."""
        found: set[int] = set()
        for c in self._span(lo, hi, self.reach):
            found |= self._cells.get(c, set())
        r = self.reach
        out = []
        for a in sorted(found):
            if a == exclude:
                continue
            tr = self.tracks[a]
            if (
                tr.lo_m[0] - r <= hi[0]
                and tr.hi_m[0] + r >= lo[0]
                and tr.lo_m[1] - r <= hi[1]
                and tr.hi_m[1] + r >= lo[1]
            ):
                out.append(tr)
        return out

    def _keep(self, agent: int, other: Track):
        p = self.problem
        return p.keepouts[(int(p.type_index[agent]), other.type)]

    def waiting_near(self, lo: np.ndarray, hi: np.ndarray, exclude: int):
        """(agent, start m, until step) of the waiting vehicles within reach of the box [lo, hi]."""
        r = self.reach
        for b, (p, until) in self.waiting.items():
            if b != exclude and lo[0] - r <= p[0] <= hi[0] + r and lo[1] - r <= p[1] <= hi[1] + r:
                yield b, p, until

    def forbidden_departures(self, agent: int, q_m: np.ndarray, arc_m: np.ndarray) -> np.ndarray:
        """(horizon,) bool: departing at step d along the move sampled at ``q_m`` (K + 1, 3), whose
        distance along the move is ``arc_m`` (K + 1,) (non-decreasing), hits another track."""
        T = self.horizon
        bad = np.zeros(T, dtype=bool)
        p0, p1 = q_m[0], q_m[-1]
        L = float(np.linalg.norm(p1 - p0))
        u = (p1 - p0) / L if L > 0 else np.zeros(3)
        uxy = u[:2]
        a2 = float(uxy @ uxy)
        lo, hi = q_m.min(axis=0), q_m.max(axis=0)
        R = self.reach
        pt = self.problem.type_index
        ta = int(pt[agent])
        for b, p, until in self.waiting_near(lo, hi, agent):
            hit = _conflict(self.problem.keepouts[(ta, int(pt[b]))], p[None] - q_m, False, SAMPLING_GROWTH_M)
            if hit.any():  # at q_k while b still waits: d + k <= until
                bad[: max(0, min(T, until - int(np.flatnonzero(hit)[0]) + 1))] = True
        near = self.near(lo, hi, agent)
        if not near:
            return bad
        # every near track's samples but its last, stacked: (track type, step t, position)
        P = np.concatenate([tr.positions_m[:-1] for tr in near], axis=0)
        t_of = np.concatenate([np.arange(tr.positions_m.shape[0] - 1) for tr in near])
        ty = np.concatenate([np.full(tr.positions_m.shape[0] - 1, tr.type) for tr in near])
        W = P[:, :2] - p0[None, :2]
        if a2 > 1e-12:
            b_ = W @ uxy
            c = np.einsum("ij,ij->i", W, W) - R * R
            disc = b_ * b_ - a2 * c
            ok = disc >= 0.0
            sq = np.sqrt(np.maximum(disc, 0.0))
            s_lo, s_hi = (b_ - sq) / a2, (b_ + sq) / a2
            ok &= (s_hi >= 0.0) & (s_lo <= L)
        else:
            ok = np.einsum("ij,ij->i", W, W) <= R * R
            s_lo = np.full(P.shape[0], -1.0)
            s_hi = np.full(P.shape[0], L + 1.0)
        rows = np.flatnonzero(ok)
        if rows.size:
            k_lo = np.searchsorted(arc_m, s_lo[rows], side="left")
            k_hi = np.searchsorted(arc_m, s_hi[rows], side="right")
            cnt = np.maximum(k_hi - k_lo, 0)
            total = int(cnt.sum())
            if total:
                rr = np.repeat(rows, cnt)
                kk = np.repeat(k_lo - np.cumsum(np.r_[0, cnt[:-1]]), cnt) + np.arange(total)
                d = P[rr] - q_m[kk]
                h = np.zeros(total, dtype=bool)
                for tb in np.unique(ty[rr]).tolist():
                    m = ty[rr] == tb
                    h[m] = _conflict(self.problem.keepouts[(ta, int(tb))], d[m], False, SAMPLING_GROWTH_M)
                dep = t_of[rr[h]] - kk[h]
                bad[dep[(dep >= 0) & (dep < T)]] = True
        # parked for good after each track's last sample: any d with d + k >= n - 1 for a hit k
        tail_from = T
        last = np.array([tr.positions_m[-1] for tr in near])
        n_of = np.array([tr.positions_m.shape[0] for tr in near])
        ty_of = np.array([tr.type for tr in near])
        K = q_m.shape[0]
        for tb in np.unique(ty_of).tolist():
            sel = np.flatnonzero(ty_of == tb)
            d = (last[sel][:, None, :] - q_m[None, :, :]).reshape(-1, 3)
            hit = _conflict(self.problem.keepouts[(ta, int(tb))], d, False, SAMPLING_GROWTH_M).reshape(sel.size, K)
            rows = np.flatnonzero(hit.any(axis=1))
            if rows.size:
                k_last = K - 1 - np.argmax(hit[rows, ::-1], axis=1)
                tail_from = min(tail_from, int(np.maximum(0, n_of[sel[rows]] - 1 - k_last).min()))
        if tail_from < T:
            bad[tail_from:] = True
        return bad

    def forbidden_holds(self, agent: int, w_m: np.ndarray) -> np.ndarray:
        """(horizon,) bool: resting at ``w_m`` (3,) at step t conflicts with another track."""
        T = self.horizon
        out = np.zeros(T, dtype=bool)
        R = self.reach
        pt = self.problem.type_index
        for b, p, until in self.waiting_near(w_m, w_m, agent):
            ko = self.problem.keepouts[(int(pt[agent]), int(pt[b]))]
            if _conflict(ko, (p - w_m)[None], True, SAMPLING_GROWTH_M)[0]:
                out[: min(T, until + 1)] = True
        for tr in self.near(w_m, w_m, agent):
            ko = self._keep(agent, tr)
            P = tr.positions_m
            n = P.shape[0]
            if _conflict(ko, (P[-1] - w_m)[None], True, SAMPLING_GROWTH_M)[0] and n - 1 < T:
                out[n - 1 :] = True
            d = P[: n - 1] - w_m[None]
            near = np.flatnonzero((np.abs(d[:, 0]) <= R) & (np.abs(d[:, 1]) <= R))
            if near.size == 0:
                continue
            mv = tr.moving[near]
            h = np.zeros(near.size, dtype=bool)
            if mv.any():
                h[mv] = _conflict(ko, d[near[mv]], False, SAMPLING_GROWTH_M)
            if (~mv).any():
                h[~mv] = _conflict(ko, d[near[~mv]], True, SAMPLING_GROWTH_M)
            idx = near[h]
            out[idx[idx < T]] = True
        return out


def _conflict(ko, d: np.ndarray, rest: bool, grow_m: float) -> np.ndarray:
    """KeepOut test of relative vectors ``d`` (M, 3), m, with the keep-out grown by ``grow_m``
    (the vectors are shrunk towards the pair's centre by it, horizontally and in distance)."""
    d = np.asarray(d, dtype=float).reshape(-1, 3)
    if grow_m <= 0.0:
        return ko.conflict(d, rest=rest)
    r = np.linalg.norm(d[:, :2], axis=1)
    shrink = np.where(r > grow_m, (r - grow_m) / np.maximum(r, 1e-12), 0.0)
    dd = d.copy()
    dd[:, :2] *= shrink[:, None]
    hit = ko.conflict(dd, rest=rest)
    # the sphere part, grown in 3-D
    sep = ko.separation_m + (ko.w_rest_m if rest else ko.w_move_m) + grow_m
    return hit | (np.einsum("ij,ij->i", d, d) < sep * sep)
