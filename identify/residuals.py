"""Residual analysis: which situation feature does the unexplained disturbance follow?

Features per sample (all SI): ``dz_m`` and ``r_m`` to the nearest source (dz > 0 when the target is
below it; NaN without sources), ``height_above_ground_m``, ``speed_xy_mps`` and ``v_z_mps`` (the
target's own velocity, world frame), ``speed_mps``. For each feature the Pearson correlation with
the residual and the correlation ratio eta (binned means; catches non-monotonic shapes such as a
peak at small r) are reported; features are ranked by max(|pearson|, eta).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

FEATURES = ("dz_m", "r_m", "height_above_ground_m", "speed_xy_mps", "v_z_mps", "speed_mps")


@dataclass(frozen=True)
class FeatureCorrelation:
    feature: str
    pearson: float  # -
    eta: float  # correlation ratio of binned means, 0..1
    n: int

    @property
    def strength(self) -> float:
        return max(abs(self.pearson), self.eta)


def sample_features(
    height_above_ground_m: np.ndarray, velocity_mps: np.ndarray, source_offsets_m: list[np.ndarray]
) -> dict[str, np.ndarray]:
    """Features (each (N,)) from heights (N,), velocities (N, 3) and each source's offsets (N, 3)."""
    n = len(height_above_ground_m)
    dz = np.full(n, np.nan)
    r = np.full(n, np.nan)
    if source_offsets_m:
        offs = np.stack(source_offsets_m)  # (S, N, 3)
        nearest = np.argmin(np.linalg.norm(offs, axis=2), axis=0)
        o = offs[nearest, np.arange(n)]
        dz, r = -o[:, 2], np.hypot(o[:, 0], o[:, 1])
    v = np.asarray(velocity_mps)
    return {
        "dz_m": dz,
        "r_m": r,
        "height_above_ground_m": np.asarray(height_above_ground_m, dtype=float),
        "speed_xy_mps": np.hypot(v[:, 0], v[:, 1]),
        "v_z_mps": v[:, 2],
        "speed_mps": np.linalg.norm(v, axis=1),
    }


def _eta(x: np.ndarray, y: np.ndarray, bins: int) -> float:
    edges = np.unique(np.quantile(x, np.linspace(0.0, 1.0, bins + 1)))
    if len(edges) < 3:
        return 0.0
    idx = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, len(edges) - 2)
    total = float(((y - y.mean()) ** 2).sum())
    if total <= 0.0:
        return 0.0
    between = 0.0
    for b in range(len(edges) - 1):
        m = idx == b
        if m.sum():
            between += m.sum() * (y[m].mean() - y.mean()) ** 2
    # small-sample bias: subtract what noise alone gives (bins - 1) / n, floor at 0
    eta_sq = between / total - (len(edges) - 2) / len(y)
    return float(np.sqrt(max(eta_sq, 0.0)))


def correlate(residual: np.ndarray, features: dict[str, np.ndarray], *, bins: int = 12) -> list[FeatureCorrelation]:
    """Correlation of ``residual`` (N,) with each feature, strongest first (NaN samples skipped)."""
    out = []
    for name, x in features.items():
        ok = np.isfinite(x) & np.isfinite(residual)
        if ok.sum() < 10 or np.std(x[ok]) == 0.0 or np.std(residual[ok]) == 0.0:
            out.append(FeatureCorrelation(name, 0.0, 0.0, int(ok.sum())))
            continue
        xs, ys = x[ok], residual[ok]
        pearson = float(np.corrcoef(xs, ys)[0, 1])
        out.append(FeatureCorrelation(name, pearson, _eta(xs, ys, bins), int(ok.sum())))
    return sorted(out, key=lambda c: -c.strength)
