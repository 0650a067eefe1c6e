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
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

# steps per time bucket: a bucket's tree is asked at a fixed cost (~20 us) and returns pairs of
# up to one bucket outside a query's window, but only with the move samples that can meet the
# window there (the chain's windows span 100-700 steps on corridor-64, docs/planner.md); 160 steps
# = 4 s of flight. Only the speed depends on it, never the answer: set watching corridor-64's query
# CPU (40, 80 and 160 steps within the noise of a loaded machine of each other)
BUCKET_STEPS = 160
PARKED_END = 2**40  # end step of a parked segment: beyond any horizon (an int64 with room for sums)
REACH_SLACK = 1e-9  # the pair search's relative widening of the reach (rounding of its distances)


class DepartureIndex:
    """Segments (positions (M, 3), m; first step t0, end step t1 (exclusive); type; agent) by
    time bucket (see module)."""

    def __init__(self, P: np.ndarray, t0: np.ndarray, t1: np.ndarray, ty: np.ndarray, ag: np.ndarray):
        self.P, self.t0, self.t1, self.ty, self.ag = P, t0, t1, ty, ag
        b0 = t0 // BUCKET_STEPS
        long = (t1 - 1) // BUCKET_STEPS > b0
        self.long_rows = np.flatnonzero(long)
        short = np.flatnonzero(~long)
        order = short[np.argsort(b0[short], kind="stable")]
        self.n_buckets = int(b0[short].max()) + 1 if short.size else 0
        self._starts = np.searchsorted(b0[order], np.arange(self.n_buckets + 1))
        self._order = order
        self._trees: dict[int, cKDTree | None] = {}
        self._long_tree = cKDTree(P[self.long_rows, :2]) if self.long_rows.size else None

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
        horizontally that can forbid a departure in [``from_step``, ``until_step``) (see module)."""
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
