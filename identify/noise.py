"""The measurement noise the identification weighs its fits by (issue 35).

:func:`noise_level` gives the integrated autocorrelation time of the residual (N correlated samples carry the
information of N / tau independent ones) and, per vehicle type and wrench channel (:data:`CHANNELS`), the
noise unit: the residual's spread at one correlation time, where slow structure cancels.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from proxplan.identify.data import Model, Unit, predict

CHANNELS = ("force_z_N", "torque_x_Nm", "torque_y_Nm", "torque_z_Nm")
"""Wrench channels selection fits, and their columns in the stacked (force, torque) wrench (N, 6)."""
CHANNEL_COLUMNS = (2, 3, 4, 5)
SCALE_FLOOR = 1e-3
"""A channel's noise unit is at least this share of its measured signal's RMS (the measurement's relative
resolution, 0.1 %): a channel the model predicts to rounding error (a yaw torque no effect touches) must
not turn rounding error into signal; a channel with no measured signal at all is left out (weight 0), -."""
TAU_SAMPLES = 40000
"""Samples (whole contiguous units) the residual's integrated autocorrelation time is estimated on."""


def stacked(force_N: np.ndarray, torque_Nm: np.ndarray) -> np.ndarray:
    """(N, 4) F_z, tau_x, tau_y, tau_z of a world-frame force (N, 3) N and torque (N, 3) N m."""
    return np.column_stack([force_N[:, 2], torque_Nm])


def integrated_autocorrelation_time(segments: Sequence[np.ndarray]) -> float:
    """Integrated autocorrelation time of a residual, in samples (1 for white noise), pooled over
    contiguous ``segments`` (each (n,), in time order).

    tau_int = 1 + 2 sum_{k=1}^{K} rho_k with the pooled autocorrelation rho_k (FFT, each segment about
    its own mean) and Sokal's automatic window: the smallest K with K >= 5 tau_int(K) (Sokal 1989; the
    usual choice in MCMC error analysis). N samples of such a residual carry the information of
    N / tau_int independent ones: a sum of squares over them is worth N / tau_int samples.
    """
    segs = [np.asarray(s, dtype=float) - np.mean(s) for s in segments if len(s) >= 8]
    if not segs:
        return 1.0
    max_lag = min(max(len(s) for s in segs) // 2, 2000)
    acov = np.zeros(max_lag + 1)
    count = np.zeros(max_lag + 1)
    for s in segs:
        n = len(s)
        f = np.fft.rfft(s, 2 * n)
        ac = np.fft.irfft(f * np.conj(f))[: min(n, max_lag + 1)]
        acov[: ac.size] += ac
        count[: ac.size] += n - np.arange(ac.size)
    ok = count > 0
    rho = np.zeros(max_lag + 1)
    rho[ok] = (acov[ok] / count[ok]) / (acov[0] / count[0]) if acov[0] > 0 else 0.0
    tau = 1.0
    for k in range(1, max_lag + 1):
        tau = 1.0 + 2.0 * float(np.sum(rho[1 : k + 1]))
        if k >= 5.0 * tau:
            break
    return float(max(tau, 1.0))


@dataclass(frozen=True)
class NoiseLevel:
    """The measurement noise the fits are weighted by: the integrated autocorrelation time ``tau`` of the F_z
    residual (samples) and, per vehicle type, the noise unit of each channel (4,) (N, N m; inf for a channel
    without measured signal, which then carries no weight)."""

    tau: float
    scale: dict[str, np.ndarray]

    def rows(self, units: Sequence[Unit]) -> np.ndarray:
        """(N, 4) the noise unit of every sample of ``units`` (stacked) and channel."""
        return np.concatenate([np.tile(self.scale[u.type], (len(u), 1)) for u in units])


def noise_level(units: Sequence[Unit], model: Model) -> NoiseLevel:
    """:class:`NoiseLevel` of ``model``'s residual on whole ``units`` at full resolution (up to
    :data:`TAU_SAMPLES` samples, every k-th unit so that all flights contribute).

    tau: :func:`proxplan.identify.calibrate.integrated_autocorrelation_time` of the F_z residual. Noise unit
    of a type's channel: the residual's second difference over one correlation time,
    sqrt(var(r(t + tau) - 2 r(t) + r(t - tau)) / 6): samples one correlation time apart are nearly
    independent, so this is the noise's spread, while a structure slower than tau (a thrust-map error, an
    effect the model lacks) cancels in the difference (a trend exactly) and does not inflate it. Floored
    at :data:`SCALE_FLOOR` of the measured signal's RMS."""
    units = [u for u in units if len(u) > 50]
    if not units:
        return NoiseLevel(1.0, {})
    total = sum(len(u) for u in units)
    step = max(1, int(np.ceil(total / TAU_SAMPLES)))
    picked = units[::step]
    seen = {u.type for u in picked}
    picked += [next(u for u in units if u.type == t) for t in sorted({u.type for u in units} - seen)]
    residuals = [(u, stacked(u.force_N, u.torque_Nm) - stacked(*predict(u, model))) for u in picked]
    tau = integrated_autocorrelation_time([r[:, 0] for _, r in residuals])
    lag = max(1, int(round(tau)))
    scale: dict[str, np.ndarray] = {}
    for vtype in sorted({u.type for u, _ in residuals}):
        diffs = [r[2 * lag :] - 2.0 * r[lag:-lag] + r[: -2 * lag] for u, r in residuals
                 if u.type == vtype and len(r) > 2 * lag]  # fmt: skip
        signal = [stacked(u.force_N, u.torque_Nm) for u, _ in residuals if u.type == vtype]
        d = np.concatenate(diffs) if diffs else np.zeros((0, 4))
        sig = np.sqrt(np.mean(np.concatenate(signal) ** 2, axis=0))
        noise = np.sqrt(np.mean(d**2, axis=0) / 6.0) if len(d) else sig
        unit = np.maximum(noise, SCALE_FLOOR * sig)
        scale[vtype] = np.where(unit > 0.0, unit, np.inf)
    return NoiseLevel(float(tau), scale)
