"""The departure query's index: the others' track segments by time bucket, each bucket a k-d tree
of their horizontal positions, built once per state of the occupancy (queries far outnumber changes:
one planning asks about 90 departure queries of one occupancy on corridor-64, then puts one track).

A query (a move sampled on the grid at q_k, k = 0..K-1, departing at any step d of a window
[from, until)) needs the pairs (segment of another track over steps [t0, t1), move sample k) that
can coincide in time - [t0 - k, t1 - k) meets the window - and in space. Time comes first: only
the buckets of ``BUCKET_STEPS`` steps that hold a segment starting in [from, until + K - 1) are
asked, each with only the move samples k that can meet the window there, then each bucket's tree gives, in one compiled dual-tree pass
(:meth:`scipy.spatial.cKDTree.sparse_distance_matrix`), the pairs within the horizontal reach of
the keep-outs - and only those pairs are tested exactly. No pair that conflicts is missed: a
conflict needs a horizontal distance below the reach (every keep-out's sphere and cut-off radii,
grown, lie within it; the pair search uses the reach widened by :data:`REACH_SLACK` against
rounding), and a segment lies in the bucket of its first step, or, when it spans more than one
bucket (a vehicle resting there, or parked for good after its last sample: the segment
[arrival, ``PARKED_END``)), in the one tree of long segments asked by every query.

**Moves that go forward along a line** (every move of a chain timed rest to rest, the default, and
runs through waypoints that do) are asked without trees: with A + s_k u the foot of sample k on the
horizontal line from the first sample to the last, s_k non-decreasing (checked; else the trees
above answer), the samples within reach r of a point P have s_k within sqrt(r'^2 - e^2) of P's
abscissa on the line (e its distance from it, r' = r plus the samples' largest distance from the
line: zero for a straight move): one ``searchsorted`` per end.
Intersected with the samples that can meet the window in time (k in [t0 - until + 1, t1 - from)),
each segment gives one range of k, and only the pairs in it are tested. The segments asked are a
slice of those sorted by first step (t0 in [from - ``SHORT_STEPS``, until + K - 1)) and every
segment lasting longer. No pair that conflicts is missed: a sample within r of P has its foot within
r' of P (triangle inequality), and r' is widened by rounding slacks. The pairs are
those within reach that can meet the window, fewer than the trees give (those can be a bucket
outside it), and the answer of a departure query is the same (tested). The occupancy asks them in one
pass (:meth:`DepartureIndex.line_forbidden`: the pairs tested and windowed without a list of pairs
of the whole index; stop 62 round 24A).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from proxplan.planner.swarm.memo import Memo

# steps per time bucket: a bucket's tree is asked at a fixed cost (~20 us) and returns pairs of
# up to one bucket outside a query's window, but only with the move samples that can meet the
# window there (the chain's windows span 100-700 steps on corridor-64, docs/planner.md); 160 steps
# = 4 s of flight. Only the speed depends on it, never the answer: set watching corridor-64's query
# CPU (40, 80 and 160 steps within the noise of a loaded machine of each other)
BUCKET_STEPS = 160
PARKED_END = 2**40  # end step of a parked segment: beyond any horizon (an int64 with room for sums)
REACH_SLACK = 1e-9  # the pair search's relative widening of the reach (rounding of its distances)
LINE_SLACK_M = 1e-9  # the straight-move search's absolute widening of the reach, m (rounding of its projections)
# the lines of the moves asked (_line_of), kept by their samples: a move is asked against many states of
# the occupancy (its chain's windows, the searches of every pass); a line holds its K abscissae (~60 on
# corridor-64, 0.5 kB), so 4096 lines stay below a few MB. Only the speed depends on it
MAX_LINES = 4096
# a segment lasting longer than this many steps is asked by every straight-move query (the others
# by a slice of the segments sorted by first step); 0.8 s of flight: only the speed depends on it
SHORT_STEPS = 16
_LINES = Memo(MAX_LINES)  # (shape, samples' bytes) -> _line_of


@dataclass(frozen=True)
class _Slice:
    """Segments of a :class:`DepartureIndex` in one order, as contiguous arrays: rows of the index,
    horizontal positions as x + iy (m; one complex product gives a point's abscissa and distance
    along and from a line), heights z (m), first and end steps, types, agents."""

    rows: np.ndarray
    xy: np.ndarray
    z: np.ndarray
    t0: np.ndarray
    t1: np.ndarray
    ty: np.ndarray
    ag: np.ndarray

    @classmethod
    def of(cls, ix: DepartureIndex, rows: np.ndarray) -> _Slice:
        P = ix.P[rows]
        return cls(
            rows,
            P[:, 0] + 1j * P[:, 1],
            np.ascontiguousarray(P[:, 2]),
            ix.t0[rows],
            ix.t1[rows],
            ix.ty[rows],
            ix.ag[rows],
        )


class DepartureIndex:
    """Segments (positions (M, 3), m; first step t0, end step t1 (exclusive); type; agent) by
    time bucket (see module)."""

    def __init__(self, P: np.ndarray, t0: np.ndarray, t1: np.ndarray, ty: np.ndarray, ag: np.ndarray):
        self.P, self.t0, self.t1, self.ty, self.ag = P, t0, t1, ty, ag
        self._bucketed = False  # the buckets and the long segments' tree: built at the first tree query
        self._trees: dict[int, cKDTree | None] = {}
        self._by_t0: tuple[_Slice, int] | None = None  # the line queries' segments: by first step, then the long

    def _buckets(self) -> None:
        """The short segments by first step's bucket and the tree of the long ones (see module; only
        :meth:`tree_pairs` reads them, and a state asked only along lines never builds them)."""
        if self._bucketed:
            return
        b0 = self.t0 // BUCKET_STEPS
        long = (self.t1 - 1) // BUCKET_STEPS > b0
        self.long_rows = np.flatnonzero(long)
        short = np.flatnonzero(~long)
        order = short[np.argsort(b0[short], kind="stable")]
        self.n_buckets = int(b0[short].max()) + 1 if short.size else 0
        self._starts = np.searchsorted(b0[order], np.arange(self.n_buckets + 1))
        self._order = order
        self._long_tree = cKDTree(self.P[self.long_rows, :2]) if self.long_rows.size else None
        self._bucketed = True

    @classmethod
    def of(cls, segments: list[tuple[np.ndarray, np.ndarray, np.ndarray, int, int]]) -> DepartureIndex:
        """The index of ``segments``: (positions (S, 3), t0 (S,), t1 (S,), type, agent) per track."""
        if not segments:
            z = np.zeros(0, dtype=np.int64)
            return cls(np.zeros((0, 3)), z, z, z, z)
        return cls(
            np.concatenate([s[0] for s in segments]),
            np.concatenate([s[1] for s in segments]).astype(np.int64),
            np.concatenate([s[2] for s in segments]).astype(np.int64),
            np.concatenate([np.full(s[0].shape[0], s[3], dtype=np.int64) for s in segments]),
            np.concatenate([np.full(s[0].shape[0], s[4], dtype=np.int64) for s in segments]),
        )

    def _tree(self, b: int) -> cKDTree | None:
        """Bucket ``b``'s tree of short segments (built when first asked; None: empty)."""
        if b not in self._trees:
            rows = self._order[self._starts[b] : self._starts[b + 1]]
            self._trees[b] = cKDTree(self.P[rows, :2]) if rows.size else None
        return self._trees[b]

    def pairs(self, q_m: np.ndarray, reach_m: float, from_step: int, until_step: int):
        """(rows (N,), k (N,)): a superset of the (segment, move sample) pairs within ``reach_m``
        horizontally that can forbid a departure in [``from_step``, ``until_step``) (see module:
        along a straight move without trees, else by the buckets' trees)."""
        got = self.line_pairs(q_m, reach_m, from_step, until_step)
        return got if got is not None else self.tree_pairs(q_m, reach_m, from_step, until_step)

    def _sorted_by_t0(self) -> tuple[_Slice, int]:
        """The short segments sorted by first step, then the segments lasting longer than
        ``SHORT_STEPS``, in one :class:`_Slice`, and the number of short ones."""
        if self._by_t0 is None:
            lasting = self.t1 - self.t0 > SHORT_STEPS
            short = np.flatnonzero(~lasting)
            rows = np.concatenate([short[np.argsort(self.t0[short], kind="stable")], np.flatnonzero(lasting)])
            self._by_t0 = (_Slice.of(self, rows), int(short.size))
        return self._by_t0

    def _line_near(self, q_m: np.ndarray, reach_m: float, from_step: int, until_step: int, exclude: int):
        """The segments near a move going forward along its line (see module), each with the range of
        move samples k it pairs with: (rows (N,), xy (N,) complex: x + iy, m, z (N,), m, t0 (N,),
        t1 (N,), type (N,), first k (N,), number of k (N,) > 0), or None where the move does not go
        forward along a line. Segments of agent ``exclude`` are left out (-1: none). The short
        segments asked (a slice by first step) and the long ones are scanned as one array, the
        short first."""
        K = q_m.shape[0]
        line = _LINES.get((q_m.shape, q_m.tobytes()), lambda: _line_of(q_m))
        if line is None:
            return None
        a0, a1, u0, u1, s, off_m = line
        r = reach_m * (1.0 + REACH_SLACK) + off_m + LINE_SLACK_M
        sl, n_short = self._sorted_by_t0()
        i0, i1 = (int(i) for i in np.searchsorted(sl.t0[:n_short], [from_step - SHORT_STEPS, until_step + K - 1]))
        a, turn = complex(a0, a1), complex(u0, -u1)  # (p - a) * turn = along + i (signed distance from the line)
        n_in = i1 - i0  # the short segments asked: sl[i0:i1], then the long: sl[n_short:]
        xy = np.concatenate([sl.xy[i0:i1], sl.xy[n_short:]])
        w = (xy - a) * turn
        keep = np.abs(w.imag) <= r
        if exclude >= 0:
            keep &= np.concatenate([sl.ag[i0:i1], sl.ag[n_short:]]) != exclude
        idx = np.flatnonzero(keep)
        w = w[idx]
        at = idx + np.where(idx < n_in, i0, n_short - n_in)  # their places in sl
        t0 = sl.t0[at]
        t1 = sl.t1[at]
        half = np.sqrt(np.maximum(r * r - w.imag * w.imag, 0.0))
        k_lo = np.maximum(np.maximum(t0 - until_step + 1, 0), np.searchsorted(s, w.real - half, side="left"))
        k_hi = np.minimum(np.minimum(t1 - from_step, K), np.searchsorted(s, w.real + half, side="right"))
        n = k_hi - k_lo
        some = np.flatnonzero(n > 0)
        at = at[some]
        return sl.rows[at], sl.xy[at], sl.z[at], t0[some], t1[some], sl.ty[at], k_lo[some], n[some]

    def line_pairs(self, q_m: np.ndarray, reach_m: float, from_step: int, until_step: int):
        """:meth:`pairs` for a move whose samples ``q_m`` go forward along the horizontal line from the
        first to the last (see module), or None when they do not (or barely move horizontally)."""
        near = self._line_near(q_m, reach_m, from_step, until_step, -1)
        if near is None:
            return None
        seg, k = _expand(near[6], near[7])
        return near[0][seg].astype(np.int64), k

    def line_forbidden(
        self,
        q_m: np.ndarray,
        reach_m: float,
        from_step: int,
        until_step: int,
        exclude: int,
        conflict: Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray],
        horizon_steps: int,
    ) -> np.ndarray | None:
        """(horizon,) bool: the departures in [``from_step``, ``until_step``) that a segment of an
        agent other than ``exclude`` forbids along a move going forward along its line (None: it does
        not; see module), ``conflict(r2, dz, types)`` the exact test of relative vectors given as their
        squared horizontal distances (P,), m^2, and heights (P,), m
        (:meth:`~proxplan.planner.swarm.keepout.GrownStack.conflict_rz`). The
        pairs of :meth:`line_pairs` (those of ``exclude`` left out), each tested once, gathered from the
        near segments only and windowed only where they conflict: a pair (segment [t0, t1), k) of
        :meth:`line_pairs` has t0 - k < until and t1 - k > from, so its departures
        [max(t0 - k, from), min(t1 - k, until)) are never empty."""
        near = self._line_near(q_m, reach_m, from_step, until_step, exclude)
        if near is None:
            return None
        _, xy, z, t0, t1, ty, k_lo, n = near
        seg, k = _expand(k_lo, n)
        dxy = xy[seg] - (q_m[:, 0] + 1j * q_m[:, 1])[k]
        dx, dy = dxy.real, dxy.imag
        hit = np.flatnonzero(conflict(dx * dx + dy * dy, z[seg] - q_m[:, 2][k], ty[seg]))
        seg, k = seg[hit], k[hit]
        return covered(np.maximum(t0[seg] - k, from_step), np.minimum(t1[seg] - k, until_step), horizon_steps)

    def tree_pairs(self, q_m: np.ndarray, reach_m: float, from_step: int, until_step: int):
        """:meth:`pairs` by the buckets' trees, for any move (see module)."""
        self._buckets()
        K = q_m.shape[0]
        tq = cKDTree(q_m[:, :2])
        r = reach_m * (1.0 + REACH_SLACK)
        rows: list[np.ndarray] = []
        ks: list[np.ndarray] = []
        if self._long_tree is not None:
            got = self._long_tree.sparse_distance_matrix(tq, r, output_type="ndarray")
            rows.append(self.long_rows[got["i"]])
            ks.append(got["j"])
        # a short segment lies within its first step's bucket b, steps [b B, (b + 1) B) (B =
        # BUCKET_STEPS): it can forbid a departure in the window with move sample k only when
        # t0 - k < until and t1 - k > from, i.e. b B - until < k < (b + 1) B - from, so each bucket
        # is asked with those samples only (none: the bucket is not asked)
        B = BUCKET_STEPS
        b_lo = max(0, from_step // B)
        b_hi = min(self.n_buckets - 1, (until_step + K - 2) // B)
        for b in range(b_lo, b_hi + 1):
            k0, k1 = max(0, b * B - until_step + 1), min(K, (b + 1) * B - from_step)
            tree = self._tree(b) if k1 > k0 else None
            if tree is None:
                continue
            tk = tq if (k0, k1) == (0, K) else cKDTree(q_m[k0:k1, :2])
            got = tree.sparse_distance_matrix(tk, r, output_type="ndarray")
            rows.append(self._order[self._starts[b] + got["i"]])
            ks.append(got["j"] + k0)
        if not rows:
            z = np.zeros(0, dtype=np.int64)
            return z, z
        return np.concatenate(rows).astype(np.int64), np.concatenate(ks).astype(np.int64)


def _line_of(q_m: np.ndarray) -> tuple[float, float, float, float, np.ndarray, float] | None:
    """A move's line (see module): its first sample's horizontal position (a0, a1), m, the unit
    vector (u0, u1) to its last, the samples' abscissae on it (K,), m, and their largest distance
    from it, m; None where the samples do not go forward along it (or barely move horizontally)."""
    K = q_m.shape[0]
    a0, a1 = float(q_m[0, 0]), float(q_m[0, 1])
    e0, e1 = float(q_m[-1, 0]) - a0, float(q_m[-1, 1]) - a1
    length = math.hypot(e0, e1)
    if K < 2 or length <= LINE_SLACK_M:
        return None
    u0, u1 = e0 / length, e1 / length
    dx, dy = q_m[:, 0] - a0, q_m[:, 1] - a1
    s = dx * u0 + dy * u1  # abscissae of the samples on the line, m
    if (s[1:] < s[:-1]).any():
        return None
    s.flags.writeable = False
    return a0, a1, u0, u1, s, float(np.abs(dx * u1 - dy * u0).max())


def _expand(k_lo: np.ndarray, n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(segment (P,), k (P,)): segment i repeated n_i times with k = k_lo_i .. k_lo_i + n_i - 1."""
    first = np.cumsum(n) - n  # where each segment's pairs start in the output
    total = int(first[-1] + n[-1]) if n.size else 0
    seg = np.repeat(np.arange(n.size), n)
    return seg, np.arange(total, dtype=np.int64) - (first - k_lo)[seg]


def covered(lo: np.ndarray, hi: np.ndarray, T: int) -> np.ndarray:
    """(T,) bool: the union of the step ranges [lo, hi) (each within [0, T])."""
    diff = np.bincount(lo, minlength=T + 1) - np.bincount(hi, minlength=T + 1)
    return np.cumsum(diff[:T]) > 0
