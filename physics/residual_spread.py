"""What the model cannot predict: the spread of the measured F_z about the prediction, by place in the jet.

The quasi-steady model predicts the MEAN jet; a vehicle in another's downwash also bobs in its turbulence
(issue 35: on day 23 the residual held 3.2 g above 1 Hz against 2.4 g below). Turbulence intensity peaks in
a round jet's shear layer, where the mean velocity falls fastest across the jet, and its energy scales with
the mean flow's. So the residual's variance is modelled, per vehicle type, as

    sigma^2 = floor_N^2 + force_share^2 sum_s F_s^2 + shear^2 W^2 sum_s g_s^2
              + stack^2 [(sum_s F_s)^2 - sum_s F_s^2] + limit^2 W^2 [some motor at a limit]
              + ground^2 W^2 min(L / (4 h), 1)^4,

with F_s the base model's F_z from source s (S0-7, N), W the target's weight (N), and g_s = k sqrt(-2 ln k)
the shear-layer shape of the jet kernel k of :func:`proxplan.physics.features.jet_kernel` (0 on the axis and
far out, largest where k = exp(-1/2): |dk/du| of the Gaussian profile). ``floor_N`` is the spread away from
every jet (measurement noise, the vehicle's own flow). The last three terms are the places the first three
miss: jets that merge in a stack (the cross terms 2 sum_{i<j} F_i F_j, zero under a single source: two
coherent jets add their push linearly, their turbulence at least as much), a motor at its floor or ceiling
(the thrust is then not what the map says: the measurement itself is uncertain, by a share of the weight),
and the ground's recirculation (the ground effect's size, (R / 4h)^2 in Cheeseman & Bennett's form with
R the rotor radius, taken here as (L / 4h)^2 with the frame size L, squared for a variance; L the target's size, h its height above
the ground). A model file keeps it (``model.residual_spread``) with the quantile that makes the 90 %
interval: |residual| <= quantile_90 sigma. A file without the last three terms reads them as zero.

A new flight's residual is one constant for the whole vehicle log (no model of the air predicts it; its cause is
not traced: not the battery as the logs record it, nor a mass error, docs/identify.md "Stop 72, round 34V") plus
the part above, which varies within the log.
The interval of a new flight holds both (issue 35, stop 71):

    sigma_total^2 = sigma^2 + flight_N^2,

``flight_N`` (N) the spread of that per-log constant between the vehicle logs of one type
(:func:`proxplan.identify.spread.fit_spread` derives it). A file without it reads it as zero (the interval of
a model saved before: the place part alone, fitted then on the residual with the offsets in it).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from proxplan.physics.features import jet_kernel

SPREAD_FORM = "jet-shear-1"
"""Name of the form above (stored with the parameters)."""


@dataclass(frozen=True)
class TypeSpread:
    """The spread parameters of one vehicle type: ``floor_N`` (N), ``force_share`` (-), ``shear`` (-), ``stack``
    (-), ``limit`` (-), ``ground`` (-) of the place part, and ``flight_N`` (N): the spread of the constant per
    vehicle log (module docstring)."""

    floor_N: float
    force_share: float = 0.0
    shear: float = 0.0
    stack: float = 0.0
    limit: float = 0.0
    ground: float = 0.0
    flight_N: float = 0.0

    def coefficients(self) -> np.ndarray:
        """(6,) the squared coefficients, in the order of :func:`spread_features`' columns."""
        return np.array([self.floor_N, self.force_share, self.shear, self.stack, self.limit, self.ground]) ** 2


@dataclass(frozen=True)
class ResidualSpread:
    """Per vehicle type, the residual's spread (module docstring), and the 90 % quantile of the standardised
    residual |r| / sigma (-) on the fit's samples."""

    by_type: Mapping[str, TypeSpread] = field(default_factory=dict)
    quantile_90: float = 1.6448536269514722  # a Gaussian's until fitted
    form: str = SPREAD_FORM
    # the 90 % quantile by the number of sources overhead (0, 1, 2 or more; a class its fit did not see holds
    # quantile_90): a stack's turbulence is intermittent, its standardised residual heavier-tailed than a
    # single jet's, so one quantile covers stacks less than it says
    quantile_90_overhead: tuple[float, ...] = ()

    def quantile_for(self, n_overhead: np.ndarray) -> np.ndarray:
        """(N,) the 90 % quantile for samples with ``n_overhead`` (N,) int sources overhead, -."""
        if not self.quantile_90_overhead:
            return np.full(np.shape(n_overhead), self.quantile_90)
        q = np.asarray(self.quantile_90_overhead, dtype=float)
        return q[np.clip(np.asarray(n_overhead, dtype=int), 0, q.size - 1)]

    def to_dict(self) -> dict:
        return {"form": self.form, "quantile_90": float(self.quantile_90),
                "quantile_90_overhead": [float(q) for q in self.quantile_90_overhead],
                "by_type": {t: {"floor_N": float(s.floor_N), "force_share": float(s.force_share),
                                "shear": float(s.shear), "stack": float(s.stack), "limit": float(s.limit),
                                "ground": float(s.ground), "flight_N": float(s.flight_N)}
                            for t, s in self.by_type.items()}}  # fmt: skip


def spread_features(
    n: int,
    source_fz_N: Sequence[np.ndarray],
    offsets_m: Sequence[np.ndarray],
    sizes_m: Sequence[float],
    weight_N: float,
    *,
    at_limit: np.ndarray | None = None,
    height_m: np.ndarray | None = None,
    size_m: float | None = None,
) -> np.ndarray:
    """(n, 6) the regressors of sigma^2 for n samples (module docstring): 1, sum_s F_s^2 (N^2),
    W^2 sum_s g_s^2 (N^2), (sum_s F_s)^2 - sum_s F_s^2 (N^2), W^2 [at a limit] (N^2), W^2 min(L/4h, 1)^4
    (N^2), from each source's base F_z (n,) N, offsets p_target - p_source (n, 3) m and size L (m), the
    target's weight (N), whether some motor is at a limit (``at_limit`` (n,) bool; None: never), its height
    above the ground (``height_m`` (n,) m; None: far) and its size (``size_m``, m). A vehicle with no source
    has only the floor and the last two."""
    f2 = np.zeros(n)
    f_sum = np.zeros(n)
    g2 = np.zeros(n)
    for fz, off, size in zip(source_fz_N, offsets_m, sizes_m):
        off = np.asarray(off, dtype=float).reshape(-1, 3)
        k = jet_kernel(-off[:, 2], np.hypot(off[:, 0], off[:, 1]), size)
        k = np.clip(k, 1e-300, 1.0)
        g = k * np.sqrt(np.maximum(-2.0 * np.log(k), 0.0))
        f2 += np.asarray(fz) ** 2
        f_sum += np.asarray(fz)
        g2 += g**2
    limit = np.zeros(n) if at_limit is None else np.asarray(at_limit, dtype=float)
    ground = np.zeros(n)
    if height_m is not None and size_m is not None:
        ground = np.minimum(size_m / (4.0 * np.maximum(np.asarray(height_m, dtype=float), 1e-3)), 1.0) ** 4
    cross = np.maximum(f_sum**2 - f2, 0.0)
    w2 = weight_N**2
    return np.column_stack([np.ones(n), f2, w2 * g2, cross, w2 * limit, w2 * ground])


def spread_N(spread: TypeSpread, features: np.ndarray) -> np.ndarray:
    """(N,) sigma_total of a new flight's F_z residual, N, from :func:`spread_features` (N, 6): the place part
    and the per-log constant's spread ``flight_N`` (module docstring)."""
    return np.sqrt(np.maximum(features @ spread.coefficients(), 0.0) + spread.flight_N**2)
