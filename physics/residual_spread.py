"""What the model cannot predict: the spread of the measured F_z about the prediction, by place in the jet.

The quasi-steady model predicts the MEAN jet; a vehicle in another's downwash also bobs in its turbulence
(issue 35: on day 23 the residual held 3.2 g above 1 Hz against 2.4 g below). Turbulence intensity peaks in
a round jet's shear layer, where the mean velocity falls fastest across the jet, and its energy scales with
the mean flow's. So the residual's variance is modelled, per vehicle type, as

    sigma^2 = floor_N^2 + force_share^2 sum_s F_s^2 + shear^2 W^2 sum_s g_s^2,

with F_s the base model's F_z from source s (S0-7, N), W the target's weight (N), and g_s = k sqrt(-2 ln k)
the shear-layer shape of the jet kernel k of :func:`proxplan.physics.features.jet_kernel` (0 on the axis and
far out, largest where k = exp(-1/2): |dk/du| of the Gaussian profile). ``floor_N`` is the spread away from
every jet (measurement noise, the vehicle's own flow). A model file keeps it (``model.residual_spread``)
with the quantile that makes the 90 % interval: |residual| <= quantile_90 sigma.
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
    """The spread parameters of one vehicle type: ``floor_N`` (N), ``force_share`` (-), ``shear`` (-)."""

    floor_N: float
    force_share: float = 0.0
    shear: float = 0.0


@dataclass(frozen=True)
class ResidualSpread:
    """Per vehicle type, the residual's spread (module docstring), and the 90 % quantile of the standardised
    residual |r| / sigma (-) on the fit's samples."""

    by_type: Mapping[str, TypeSpread] = field(default_factory=dict)
    quantile_90: float = 1.6448536269514722  # a Gaussian's until fitted
    form: str = SPREAD_FORM

    def to_dict(self) -> dict:
        return {"form": self.form, "quantile_90": float(self.quantile_90),
                "by_type": {t: {"floor_N": float(s.floor_N), "force_share": float(s.force_share),
                                "shear": float(s.shear)} for t, s in self.by_type.items()}}  # fmt: skip


def spread_features(
    n: int,
    source_fz_N: Sequence[np.ndarray],
    offsets_m: Sequence[np.ndarray],
    sizes_m: Sequence[float],
    weight_N: float,
) -> np.ndarray:
    """(n, 3) the regressors of sigma^2 for n samples: 1, sum_s F_s^2 (N^2), W^2 sum_s g_s^2 (N^2), from each
    source's base F_z (n,) N, offsets p_target - p_source (n, 3) m and size L (m), and the target's weight
    (N); a vehicle with no source has only the floor."""
    f2 = np.zeros(n)
    g2 = np.zeros(n)
    for fz, off, size in zip(source_fz_N, offsets_m, sizes_m):
        off = np.asarray(off, dtype=float).reshape(-1, 3)
        k = jet_kernel(-off[:, 2], np.hypot(off[:, 0], off[:, 1]), size)
        k = np.clip(k, 1e-300, 1.0)
        g = k * np.sqrt(np.maximum(-2.0 * np.log(k), 0.0))
        f2 += np.asarray(fz) ** 2
        g2 += g**2
    return np.column_stack([np.ones(n), f2, weight_N**2 * g2])


def spread_N(spread: TypeSpread, features: np.ndarray) -> np.ndarray:
    """(N,) sigma of the F_z residual, N, from :func:`spread_features` (N, 3)."""
    coef = np.array([spread.floor_N**2, spread.force_share**2, spread.shear**2])
    return np.sqrt(np.maximum(features @ coef, 0.0))
