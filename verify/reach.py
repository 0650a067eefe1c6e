"""Which vehicle pairs can matter, and when: the verifier's pair and stack checks evaluate the model
only on (pair, sample) rows within reach, found with a spatial index, instead of every pair.

*Usage bound* q of a (source, target) pair at an offset: max_i |delta f_i| / min(up headroom, down
headroom), the per-motor thrust changes (:func:`proxplan.physics.authority.motor_thrust_changes_N`)
of the source's wrench (:func:`proxplan.costmaps.pair_wrench`, the scenario's effects included)
over the smaller headroom. Usage is the largest thrust change over its headroom, so leaving a source
out of a sum moves the usage by at most q (and q of a sum is at most the sum of the q).

*Usage grid* (:func:`usage_grid`): q evaluated with the model on horizontal nodes (every 2 cm to
0.2 m, then 4 % apart), azimuths (three in [0, pi/4] for the axisymmetric jet on an X-frame, eight
around with effects) and vertical separations across the plan's range (2 cm apart without
effects), worst over azimuth; outwards until a whole block of nodes beyond twice the last node
above :data:`NEGLIGIBLE_USAGE` stays three orders below it (the Gaussian jet, S0-2, has faded), or
until the plan's horizontal extent. *Reach*: one node beyond the outermost node above the
threshold, plus 5 % (``inf`` when it is still above at the plan's extent: every pair counts). A
source beyond its reach changes a usage by less than 1e-12, and 255 of them by less than 3e-10.
:meth:`UsageGrid.bound` bounds q in a box of offsets (between nodes by log-linear interpolation and
a factor 2), for rows that may be skipped or screened.

*Candidate rows* (:func:`pairs_within`): for windows of consecutive samples, a
``scipy.spatial.cKDTree`` of the vehicles' horizontal positions in the middle of the window, queried
with the largest radius grown by how far any vehicle moves within the window; each pair it returns
is then tested at every sample of the window against its own radius.

*Counts above* (:func:`counts_above`): per (vehicle, sample), how many others are above it by more
than 1e-6 m (the verifier's "below a source"), counted exactly by sorting heights, whatever the
horizontal distance.

Plans of at most :data:`ALL_PAIRS_ROWS` (target, source, sample) rows evaluate every pair
(:func:`every_pair`): cheap there, and the numbers are the per-pair model's up to rounding.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from proxplan.costmaps import effects_key, effects_of_key, pair_wrench
from proxplan.physics import PROFILE_CUTOFF, Effect, ModelOptions, Vehicle, motor_thrust_changes_N

NEGLIGIBLE_USAGE = 1e-12
"""Authority usage, -, below which a source's contribution is left out (per source and sample)."""
ALL_PAIRS_ROWS = 200_000
"""Up to this many (target, source, sample) rows a plan's pairs are all evaluated (every reach
infinite): it costs little, and the numbers are the per-pair model's up to rounding."""
MIN_DZ_M = 1e-6  # a source is above a target when higher by more than this, m (as verify and physics.stack)
_R_LINEAR_M = 0.2  # the reach grid's horizontal nodes are 2 cm apart up to here, m
_R_GROWTH = 1.04  # then grow by this ratio per node, -
_R_BLOCK = 12  # horizontal nodes per evaluation block
_N_DZ = 17  # vertical nodes at least (with effects: exactly), -
_DZ_STEP_M = 0.02  # vertical node spacing without effects, m
BOUND_FACTOR = 2.0
"""Margin of :meth:`UsageGrid.bound` over its node values, for the variation between nodes, -."""
_REACH_MARGIN = 1.05
_WINDOW = 16  # samples per spatial-index window


def _round_up(x: float, step: float) -> float:
    return step * math.ceil(max(x, 0.0) / step - 1e-12)


@dataclass(frozen=True, eq=False)
class UsageGrid:
    """The usage bound q of a (source, target) pair (module docstring) on a grid: horizontal nodes
    ``r_m`` (R,), m, vertical separations ``dz_m`` (D,), m (target below), ``q`` (R, D) the worst
    over azimuth, -; ``reach_m`` the pair's reach, m (``math.inf``: still above the threshold at
    the grid's last node, 0: never above it)."""

    r_m: np.ndarray
    dz_m: np.ndarray
    q: np.ndarray
    reach_m: float

    def bound(self, r_m: np.ndarray, dz_lo_m: np.ndarray, dz_hi_m: np.ndarray) -> np.ndarray:
        """(T,) -: at least q anywhere at horizontal distance >= ``r_m`` and dz in [``dz_lo_m``,
        ``dz_hi_m``] (each (T,), m, inside the grid's range), times :data:`BOUND_FACTOR`: q made
        non-increasing in r (the largest value from each node outwards), interpolated in r
        log-linearly between the two nodes around r, maximised over the vertical nodes from the
        one at or below the interval to the one at or above it. The jet's Gaussian makes log q
        concave in r, so the chord lies below it between nodes, by a factor exp(c_rad h^2 /
        (4 a^2)) at node spacing h (about 1.02 at the grid's spacing); the factor 2 covers that.
        The model leaves rows whose Gaussian exponent exceeds PROFILE_CUTOFF at zero, so q drops
        from about exp(-PROFILE_CUTOFF) of its peak to 0 between two nodes, where log q is not
        concave: the hull is floored at max(q) exp(-PROFILE_CUTOFF) (the largest value such a row
        could have held), 2e-22 of the peak, ten orders below NEGLIGIBLE_USAGE."""
        hull = np.maximum.accumulate(self.q[::-1], axis=0)[::-1]
        floor = max(float(self.q.max(initial=0.0)) * math.exp(-PROFILE_CUTOFF), 1e-300)
        log_hull = np.log(np.maximum(hull, floor))
        i = np.clip(np.searchsorted(self.r_m, r_m, side="right") - 1, 0, self.r_m.size - 1)
        nxt = np.minimum(i + 1, self.r_m.size - 1)
        span = self.r_m[nxt] - self.r_m[i]
        f = np.clip(np.where(span > 0.0, (r_m - self.r_m[i]) / np.where(span > 0.0, span, 1.0), 0.0), 0.0, 1.0)
        lo = np.clip(np.searchsorted(self.dz_m, dz_lo_m, side="right") - 1, 0, self.dz_m.size - 1)
        hi = np.clip(np.searchsorted(self.dz_m, dz_hi_m, side="left"), 0, self.dz_m.size - 1)
        out = np.full(np.shape(r_m), -np.inf)
        for w in range(int(np.max(hi - lo, initial=0)) + 1):
            j = np.minimum(lo + w, hi)
            out = np.maximum(out, (1.0 - f) * log_hull[i, j] + f * log_hull[nxt, j])
        return BOUND_FACTOR * np.exp(out)


def usage_grid(
    source: Vehicle,
    target: Vehicle,
    options: ModelOptions,
    effects: tuple[Effect, ...],
    *,
    dz_lo_m: float,
    dz_hi_m: float,
    r_max_m: float,
) -> UsageGrid:
    """The :class:`UsageGrid` of ``source`` over ``target`` for vertical separations dz (target
    below the source, m) in [``dz_lo_m``, ``dz_hi_m``] and horizontal distances up to ``r_max_m``,
    m. The range is widened to multiples of 0.25 m (dz) and powers of two (r) so plans share the
    cache."""
    lo = -_round_up(-dz_lo_m, 0.25) if dz_lo_m < 0 else 0.0
    hi = _round_up(dz_hi_m, 0.25)
    r_max = 2.0 ** math.ceil(math.log2(max(r_max_m, 0.25)))
    return _grid(source, target, options, effects_key(effects), lo, hi, r_max)


def every_pair(n_vehicles: int, n_samples: int) -> bool:
    """True when a plan is small enough to evaluate every pair (:data:`ALL_PAIRS_ROWS`)."""
    return n_vehicles * (n_vehicles - 1) * n_samples <= ALL_PAIRS_ROWS


def _r_nodes(r_max: float) -> np.ndarray:
    """Horizontal nodes, m: every 2 cm to 0.2 m, then growing by 4 % per node, the last >= r_max."""
    n_geo = int(math.ceil(math.log(max(r_max, _R_LINEAR_M) / _R_LINEAR_M) / math.log(_R_GROWTH))) + 1
    return np.concatenate([np.arange(0.0, _R_LINEAR_M, 0.02), _R_LINEAR_M * _R_GROWTH ** np.arange(n_geo)])


@lru_cache(maxsize=256)
def _grid(source: Vehicle, target: Vehicle, options: ModelOptions, key, dz_lo: float, dz_hi: float, r_max: float):
    effects = effects_of_key(key)
    r = _r_nodes(r_max)
    n_dz = _N_DZ if effects else max(_N_DZ, int(math.ceil((dz_hi - dz_lo) / _DZ_STEP_M)) + 1)
    dz = np.linspace(dz_lo, dz_hi, n_dz)
    if dz_lo >= 0.0:  # above only (dz > 0, from just above zero), unless the range reaches below
        dz = np.unique(np.concatenate([dz[dz > 0.0], [1e-9]]))
    # axisymmetric jet on an X-frame: azimuths in [0, pi/4] stand for all; effects may break that
    az = np.linspace(0.0, 2.0 * np.pi, 8, endpoint=False) if effects else np.array([0.0, np.pi / 8, np.pi / 4])
    headroom = min(
        target.max_thrust_per_rotor_N - target.hover_thrust_per_rotor_N,
        target.hover_thrust_per_rotor_N - target.min_motor_thrust_N,
    )
    blocks = []
    last = -1  # outermost node at or above the threshold
    for b0 in range(0, r.size, _R_BLOCK):
        rb = r[b0 : b0 + _R_BLOCK]
        rr, aa, zz = np.meshgrid(rb, az, dz, indexing="ij")
        off = np.column_stack([(rr * np.cos(aa)).ravel(), (rr * np.sin(aa)).ravel(), -zz.ravel()])
        force, torque = pair_wrench(source, target, off, options, effects)
        change = np.abs(motor_thrust_changes_N(target, force, torque)).max(axis=1)
        q = (change / headroom).reshape(rr.shape).max(axis=1)  # (block, D) worst over azimuth
        blocks.append(q)
        hit = np.flatnonzero(q.max(axis=1) >= NEGLIGIBLE_USAGE)
        if hit.size:
            last = b0 + int(hit[-1])
        elif rb[0] >= 2.0 * r[max(last, 0)] and float(q.max()) < 1e-3 * NEGLIGIBLE_USAGE:
            break  # a whole block beyond twice the last hit, three orders below: the jet has faded
    q_all = np.concatenate(blocks)
    if last < 0:
        reach = 0.0
    elif last >= r.size - 1:
        reach = math.inf
    else:
        reach = float(r[last + 1]) * _REACH_MARGIN
    return UsageGrid(r[: q_all.shape[0]], dz, q_all, reach)


def pairs_within(xy_m: np.ndarray, radius_m: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every (i, j, sample) with i < j whose horizontal centre distance is at most
    ``radius_m[i, j]`` (N, N), m, for horizontal positions ``xy_m`` (N, M, 2), m; int arrays,
    ordered by window, then pair, then sample."""
    from scipy.spatial import cKDTree

    n, m = xy_m.shape[:2]
    finite = radius_m[np.isfinite(radius_m)]
    r_big = float(finite.max()) if finite.size else 0.0
    every = bool(np.any(np.isinf(radius_m)))
    out_i, out_j, out_m = [], [], []
    for w0 in range(0, m, _WINDOW):
        seg = xy_m[:, w0 : w0 + _WINDOW]  # (N, W, 2)
        centre = seg[:, seg.shape[1] // 2]
        moved = float(np.sqrt(((seg - centre[:, None, :]) ** 2).sum(axis=2)).max()) if n else 0.0
        if every:
            ii, jj = np.triu_indices(n, 1)
        else:
            pairs = cKDTree(centre).query_pairs(r_big + 2.0 * moved + 1e-9, output_type="ndarray")
            ii, jj = pairs[:, 0], pairs[:, 1]
        if ii.size == 0:
            continue
        d = np.hypot(seg[ii, :, 0] - seg[jj, :, 0], seg[ii, :, 1] - seg[jj, :, 1])  # (P, W)
        p, k = np.nonzero(d <= radius_m[ii, jj][:, None])
        out_i.append(ii[p])
        out_j.append(jj[p])
        out_m.append(w0 + k)
    if not out_i:
        empty = np.zeros(0, dtype=np.intp)
        return empty, empty, empty
    return np.concatenate(out_i), np.concatenate(out_j), np.concatenate(out_m)


def counts_above(z_m: np.ndarray, weight: np.ndarray | None = None) -> np.ndarray:
    """(N, M): per vehicle and sample, how many other vehicles are higher by more than
    :data:`MIN_DZ_M` (z_s - z_t > 1e-6 m exactly as the checks compute it), for heights ``z_m``
    (N, M), m; with ``weight`` (N, M) bool, how many of those have weight True."""
    n, m = z_m.shape
    order = np.argsort(z_m, axis=0, kind="stable")
    zs = np.take_along_axis(z_m, order, axis=0)  # (N, M) ascending per sample
    w = (
        np.ones((n, m), dtype=np.int64)
        if weight is None
        else np.take_along_axis(weight.astype(np.int64), order, axis=0)
    )
    tail = np.concatenate([np.cumsum(w[::-1], axis=0)[::-1], np.zeros((1, m), dtype=np.int64)])  # (N+1, M)
    pos = np.empty((n, m), dtype=np.intp)
    for k in range(m):
        pos[:, k] = np.searchsorted(zs[:, k], z_m[:, k] + MIN_DZ_M, side="right")
    cols = np.broadcast_to(np.arange(m), (n, m))
    while True:  # first sorted index whose height difference, as subtracted, exceeds the threshold
        down = (pos > 0) & (zs[np.maximum(pos - 1, 0), cols] - z_m > MIN_DZ_M)
        up = (pos < n) & ~(zs[np.minimum(pos, n - 1), cols] - z_m > MIN_DZ_M)
        if not (down.any() or up.any()):
            break
        pos = pos - down + up
    return tail[pos, cols]
