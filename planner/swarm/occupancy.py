"""What the other vehicles forbid one vehicle: departure times of a move, hold times of a point, on
the swarm's time grid, against every other vehicle's :class:`~proxplan.planner.swarm.tracks.GridTrack`.

**Space-time hash.** Each track's samples are cut into segments (a resting stretch - same place,
same moving flag - is one segment with its step range; a moving sample is one each), and the
segments into runs in one horizontal cell (cells of the largest keep-out reach): a cell lists
(agent, segments) per run, so a query collects only the segments of other tracks that are in a cell
within reach of the queried place, whatever the tracks do elsewhere and elsewhen, and a vehicle
waiting somewhere counts once, not once per step. A track parked for good (after its
last sample) is listed apart, by the cell of its end; a *predicted* track (``vanishes``) is not.

**Departures.** For a move sampled on the grid at q_k (k = 0..K, a straight line or a flight
through waypoints), departing at step d puts the vehicle at q_k at step d + k; a sample pair
(track j at step t, move sample k) that violates the pair's keep-out forbids the single departure
d = t - k, and one that rests over steps [t0, t1) the departures t0 - k .. t1 - 1 - k. Only the
pairs near in time and space are tested (:mod:`proxplan.planner.swarm.departures`: the segments by
time bucket, each bucket a k-d tree, built once per state of the occupancy), so the cost grows with
how long others are near the move. A parked track forbids a whole range of departures at once. Tests
use the moving keep-out (the vehicle moves); holds use the resting keep-out where the other vehicle
rests too, as the verifier does. Samples are ``GRID_DT_S`` apart; the keep-outs are grown for that
(the chord between two samples of a relative motion of at most 2 v_max GRID_DT_S stays outside a
keep-out grown by :data:`SAMPLING_GROWTH_M`).
"""

from __future__ import annotations

import hashlib

import numpy as np

from proxplan.planner.swarm.departures import PARKED_END, DepartureIndex, covered
from proxplan.planner.swarm.keepout import GrownStack, grown_stack
from proxplan.planner.swarm.problem import SwarmProblem
from proxplan.planner.swarm.tracks import GridTrack

SAMPLING_GROWTH_M = 0.005  # keep-out growth covering motion between grid samples, m
MIN_CELL_M = 0.5  # smallest hash cell, m (a smaller reach would make the hash fine-grained for nothing)


class Occupancy:
    """The tracks of every vehicle of ``problem`` but the one being (re)planned (see module)."""

    def __init__(self, problem: SwarmProblem, tracks: list[GridTrack], horizon_steps: int):
        self.problem = problem
        self.horizon = int(horizon_steps)
        self.reach = problem.reach_xy_m + SAMPLING_GROWTH_M
        self.cell = max(MIN_CELL_M, self.reach)
        self.tracks: dict[int, GridTrack] = {}
        self._runs: dict[tuple[int, int], list[tuple[int, int, int]]] = {}  # cell -> (agent, segments s0:s1)
        # agent -> its segments: (positions (S, 3), first step (S,), end step (S,), moving (S,))
        self._segments: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = {}
        self._parked: dict[tuple[int, int], set[int]] = {}  # cell of the end -> agents parked there
        self._cells_of: dict[int, set[tuple[int, int]]] = {}
        # cell -> its runs' segments as arrays (samples_near's layout), built when first queried and
        # dropped when a track in the cell is put or removed (queries far outnumber changes)
        self._cell_arrays: dict[tuple[int, int], tuple[np.ndarray, ...]] = {}
        self._n_types = 1 + max(max(k) for k in problem.keepouts)
        self._stacks: dict[tuple[int, bool], GrownStack] = {}  # (type a, at rest) -> its keep-outs, grown
        self._reach_by_type: dict[int, float] = {}
        self._index: DepartureIndex | None = None  # the departure query's index (None: build when asked)
        # (type, point bytes) -> forbidden_holds' answer, for this state of the tracks (emptied by put/remove:
        # a search asks the same points again, e.g. a route's start and end after the straight line's)
        self._holds: dict[tuple[int, bytes], np.ndarray] = {}
        self._digests: dict[int, bytes] = {}  # agent -> digest of its track (content_key)
        self._key: bytes | None = None  # content_key (None: compute when asked)
        for tr in tracks:
            self.put(tr)

    def _reach_of(self, ta: int) -> float:
        """The largest horizontal distance at which type ``ta`` conflicts with any type while
        moving, grown by :data:`SAMPLING_GROWTH_M`, m (its keep-outs' spheres and cut-offs lie within)."""
        got = self._reach_by_type.get(ta)
        if got is None:
            kos = [ko for (a, _), ko in self.problem.keepouts.items() if a == ta]
            got = self._reach_by_type[ta] = max(ko.reach_xy_m for ko in kos) + SAMPLING_GROWTH_M
        return got

    def stack(self, ta: int, rest: bool) -> GrownStack:
        """Type ``ta``'s keep-outs against every type, grown by :data:`SAMPLING_GROWTH_M`."""
        key = (ta, rest)
        got = self._stacks.get(key)
        if got is None:
            got = grown_stack(self.problem.keepouts, ta, self._n_types, rest=rest, grow_m=SAMPLING_GROWTH_M)
            self._stacks[key] = got
        return got

    # -- the hash -------------------------------------------------------------------------------------
    def _cell(self, xy: np.ndarray) -> np.ndarray:
        return np.floor(np.asarray(xy, dtype=float) / self.cell).astype(np.int64)

    def _cells_within(self, lo: np.ndarray, hi: np.ndarray) -> list[tuple[int, int]]:
        c0 = self._cell(np.asarray(lo[:2]) - self.reach)
        c1 = self._cell(np.asarray(hi[:2]) + self.reach)
        return [(x, y) for x in range(int(c0[0]), int(c1[0]) + 1) for y in range(int(c0[1]), int(c1[1]) + 1)]

    def put(self, track: GridTrack) -> None:
        """Add ``track`` (replacing that agent's previous one)."""
        self.remove(track.agent)
        self._index = None
        self._holds.clear()
        a = track.agent
        self.tracks[a] = track
        self._digests[a] = track_digest(track)
        self._key = None
        n = track.positions_m.shape[0] - (0 if track.vanishes else 1)  # the parked end apart
        cells: set[tuple[int, int]] = set()
        if n > 0:
            P, mv = track.positions_m[:n], track.moving[:n]
            # segments: a resting stretch (same place, same moving flag) is one, a moving sample one each
            new = np.r_[True, np.any(P[1:] != P[:-1], axis=1) | (mv[1:] != mv[:-1])]
            t0 = np.flatnonzero(new)
            t1 = np.r_[t0[1:], n]
            c = self._cell(P[t0, :2])
            self._segments[a] = (P[t0], t0, t1, mv[t0])
            change = np.flatnonzero(np.any(np.diff(c, axis=0) != 0, axis=1)) + 1
            for s0, s1 in zip(np.r_[0, change].tolist(), np.r_[change, t0.size].tolist()):
                key = (int(c[s0, 0]), int(c[s0, 1]))
                self._runs.setdefault(key, []).append((a, s0, s1))
                self._cell_arrays.pop(key, None)
                cells.add(key)
        if not track.vanishes:
            end = self._cell(track.end_m[:2])
            key = (int(end[0]), int(end[1]))
            self._parked.setdefault(key, set()).add(a)
            cells.add(key)
        self._cells_of[a] = cells

    def remove(self, agent: int) -> GridTrack | None:
        old = self.tracks.pop(agent, None)
        if old is not None:
            self._index = None
            self._key = None
            self._holds.clear()
        self._digests.pop(agent, None)
        self._segments.pop(agent, None)
        for key in self._cells_of.pop(agent, set()):
            runs = self._runs.get(key)
            if runs:
                self._runs[key] = [r for r in runs if r[0] != agent]
                self._cell_arrays.pop(key, None)
            parked = self._parked.get(key)
            if parked:
                parked.discard(agent)
        return old

    def _cell_segments(self, key: tuple[int, int]) -> tuple[np.ndarray, ...] | None:
        """The segments of every run in cell ``key``, as samples_near returns them (None: empty)."""
        got = self._cell_arrays.get(key)
        if got is None:
            runs = self._runs.get(key)
            if not runs:
                return None
            parts = []
            for a, s0, s1 in runs:
                P, t0, t1, mv = self._segments[a]
                n = s1 - s0
                parts.append(
                    (P[s0:s1], t0[s0:s1], t1[s0:s1], np.full(n, self.tracks[a].type), mv[s0:s1], np.full(n, a))
                )
            got = tuple(np.concatenate([p[i] for p in parts]) for i in range(6))
            self._cell_arrays[key] = got
        return got

    def samples_near(self, lo: np.ndarray, hi: np.ndarray, exclude: int, from_step: int = 0):
        """Segments of other tracks (a resting stretch, or one moving sample; the parked end apart) in
        cells within reach of the box [lo, hi] (m) that last beyond ``from_step``: (positions (M, 3),
        first step (M,), end step (M,, exclusive), type (M,), moving (M,), agent (M,))."""
        cells = [c for c in (self._cell_segments(key) for key in self._cells_within(lo, hi)) if c is not None]
        if not cells:
            z = np.zeros(0, dtype=np.int64)
            return np.zeros((0, 3)), z, z, z, np.zeros(0, dtype=bool), z
        P, t0, t1, ty, mv, ag = (
            (np.concatenate([c[i] for c in cells]) for i in range(6)) if len(cells) > 1 else cells[0]
        )
        keep = (ag != exclude) & (t1 > from_step)
        return P[keep], np.maximum(t0[keep], from_step), t1[keep], ty[keep], mv[keep], ag[keep]

    def parked_near(self, lo: np.ndarray, hi: np.ndarray, exclude: int) -> list[GridTrack]:
        """Tracks parked for good in a cell within reach of the box [lo, hi] (m)."""
        found: set[int] = set()
        for key in self._cells_within(lo, hi):
            found |= self._parked.get(key, set())
        found.discard(exclude)
        return [self.tracks[a] for a in sorted(found)]

    def near(self, lo: np.ndarray, hi: np.ndarray, exclude: int) -> list[GridTrack]:
        """Tracks with a sample, or parked, in a cell within reach of the box [lo, hi] (m)."""
        found: set[int] = set()
        for key in self._cells_within(lo, hi):
            found |= {a for a, _, _ in self._runs.get(key, ())}
            found |= self._parked.get(key, set())
        found.discard(exclude)
        return [self.tracks[a] for a in sorted(found)]

    def content_key(self) -> bytes:
        """A digest of what every query depends on: the horizon and, per agent, its track's type,
        samples, moving flags and whether it vanishes (not the order the tracks were put in:
        every query is a union over the tracks). Equal keys give equal answers (swarm.memo)."""
        if self._key is None:
            h = hashlib.blake2b(digest_size=32)
            h.update(np.int64(self.horizon).tobytes())
            for a in sorted(self._digests):
                h.update(np.int64(a).tobytes())
                h.update(self._digests[a])
            self._key = h.digest()
        return self._key

    # -- the queries ----------------------------------------------------------------------------------
    def forbidden_departures(
        self, agent: int, q_m: np.ndarray, from_step: int = 0, until_step: int | None = None
    ) -> np.ndarray:
        """(horizon,) bool: departing at step d along the move sampled on the grid at ``q_m``
        (K, 3), m, hits another track, for ``from_step`` <= d < ``until_step`` (None: the
        horizon); False outside that window. Only the pairs (segment, move sample) near in time
        and space are tested (:class:`~proxplan.planner.swarm.departures.DepartureIndex`)."""
        T = self.horizon
        until = T if until_step is None else min(T, max(int(until_step), from_step))
        if until <= from_step:
            return np.zeros(T, dtype=bool)
        q = np.asarray(q_m, dtype=float)
        ix = self._departure_index()
        ta = int(self.problem.type_index[agent])
        exclude = agent if agent in self.tracks else -1  # its own track is no obstacle
        stack = self.stack(ta, False)
        along = ix.line_forbidden(q, self._reach_of(ta), from_step, until, exclude, stack.conflict_rz, T)
        if along is not None:  # a move going forward along its line: the same pairs, tested in one pass
            return along
        rows, kk = ix.tree_pairs(q, self._reach_of(ta), from_step, until)
        # a hit of segment [t0, t1) with move sample k forbids the departures t0 - k .. t1 - 1 - k
        lo_d = np.maximum(ix.t0[rows] - kk, from_step)
        hi_d = np.minimum(ix.t1[rows] - kk, until)  # exclusive
        keep = hi_d > lo_d
        if agent in self.tracks:  # its own track is no obstacle
            keep &= ix.ag[rows] != agent
        rows, kk, lo_d, hi_d = rows[keep], kk[keep], lo_d[keep], hi_d[keep]
        h = stack.conflict(ix.P[rows] - q[kk], ix.ty[rows])
        return covered(lo_d[h], hi_d[h], T)

    def _departure_index(self) -> DepartureIndex:
        """The index of every track's segments, the parked ends as segments [arrival, for good)
        (built when first asked after a change)."""
        if self._index is None:
            parts = []
            for a in sorted(self.tracks):
                tr = self.tracks[a]
                seg = self._segments.get(a)
                if seg is not None:
                    parts.append((seg[0], seg[1], seg[2], tr.type, a))
                if not tr.vanishes:
                    arr = np.array([tr.arrival_step])
                    parts.append((tr.end_m[None], arr, np.array([PARKED_END]), tr.type, a))
            self._index = DepartureIndex.of(parts)
        return self._index

    def forbidden_holds(self, agent: int, w_m: np.ndarray) -> np.ndarray:
        """(horizon,) bool: resting at ``w_m`` (3,) at step t conflicts with another track (read-only:
        the answer is kept for this state of the tracks and given back to the same question)."""
        w = np.ascontiguousarray(w_m, dtype=float)
        ta = int(self.problem.type_index[agent])
        key = (ta, w.tobytes()) if agent not in self.tracks else None  # its own track: not the others' state
        got = self._holds.get(key) if key is not None else None
        if got is None:
            got = self._forbidden_holds(agent, ta, w)
            got.flags.writeable = False
            if key is not None:
                self._holds[key] = got
        return got

    def _forbidden_holds(self, agent: int, ta: int, w: np.ndarray) -> np.ndarray:
        """:meth:`forbidden_holds` asked."""
        T = self.horizon
        out = np.zeros(T, dtype=bool)
        P, t0, t1, ty, mv, _ = self.samples_near(w, w, agent)
        if P.shape[0]:
            d = P - w[None]
            near = np.flatnonzero((np.abs(d[:, 0]) <= self.reach) & (np.abs(d[:, 1]) <= self.reach))
            if near.size:
                h = np.zeros(near.size, dtype=bool)
                for rest in (False, True):
                    m = mv[near] != rest
                    if m.any():
                        h[m] = self.stack(ta, rest).conflict(d[near[m]], ty[near[m]])
                out |= covered(np.minimum(t0[near[h]], T), np.minimum(t1[near[h]], T), T)
        parked = [tr for tr in self.parked_near(w, w, agent) if tr.arrival_step < T]
        if parked:  # the parked ends in one test
            ends = np.stack([tr.end_m for tr in parked]) - w[None]
            hit = self.stack(ta, True).conflict(ends, np.array([tr.type for tr in parked]))
            if hit.any():
                out[min(tr.arrival_step for tr, h in zip(parked, hit) if h) :] = True
        return out

    def conflicting_agents(self, track: GridTrack) -> set[int]:
        """The agents whose tracks conflict with ``track`` (of its own agent) at some common grid step."""
        a = track.agent
        ta = int(self.problem.type_index[a])
        found: set[int] = set()
        for other in self.near(track.lo_m, track.hi_m, a):
            n = max(track.arrival_step, other.arrival_step) + 1
            steps = np.arange(n)
            if other.vanishes:
                steps = steps[: other.arrival_step + 1]
            d = other.position_at_steps(steps) - track.position_at_steps(steps)
            # as the queries see it: the moving keep-out along a move of ``track`` (its ends too),
            # elsewhere the resting one where the other rests as well
            moving = _at(track.in_move, track, steps) | _at(other.moving, other, steps)
            hit = np.zeros(steps.size, dtype=bool)
            for rest in (False, True):
                m = moving != rest
                if m.any():
                    hit[m] = self.stack(ta, rest).conflict(d[m], np.full(int(m.sum()), other.type))
            if hit.any():
                found.add(other.agent)
        return found


def track_digest(track: GridTrack) -> bytes:
    """Digest of what the queries read of ``track`` (its agent aside): type, whether it vanishes,
    its grid samples and moving flags (its arrival and end are its last sample)."""
    h = hashlib.blake2b(digest_size=32)
    h.update(np.array([track.type, int(track.vanishes), track.positions_m.shape[0]], dtype=np.int64).tobytes())
    h.update(np.ascontiguousarray(track.positions_m, dtype=np.float64).tobytes())
    h.update(np.ascontiguousarray(track.moving, dtype=bool).tobytes())
    return h.digest()


def _at(flags: np.ndarray, track: GridTrack, steps: np.ndarray) -> np.ndarray:
    """Per-sample ``flags`` of ``track`` at ``steps`` (False once it is parked)."""
    inside = steps <= track.arrival_step
    out = np.zeros(steps.size, dtype=bool)
    out[inside] = flags[steps[inside]]
    return out


def _conflict(ko, d: np.ndarray, rest: bool, grow_m: float) -> np.ndarray:
    """KeepOut test of relative vectors ``d`` (M, 3), m, with the keep-out grown by ``grow_m``
    (the vectors are shrunk towards the pair's centre by it, horizontally and in distance): the
    definition; the queries use the same test stacked over types (:class:`GrownStack`, tested
    equal to this one)."""
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
