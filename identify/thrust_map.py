"""Delivered motor thrust from PWM and battery voltage (saturation-aware), per vehicle type.

The Neural-Swarm logs hold, per motor, the firmware's *desired* force ``u[N]`` and the PWM command it
sent (normalised 0..1), plus the battery voltage. The firmware turns a desired force into PWM with a
voltage-compensated static map, so while a motor is not saturated

    u_N = P(x),    x = pwm * Vbat  (V, the mean voltage across the motor)

with P a cubic (the firmware's own thrust map is a polynomial in PWM and Vbat; the Crazyflie 2.0
map of Förster 2015, eq. 3.3, is a quadratic in PWM at fixed voltage). When a motor saturates, PWM
stops at its ceiling (on these logs x ~ 3.3 V) while ``u[N]`` keeps growing (up to ~10x what the
motor can give): the S0-11 measurement with ``u[N]`` then reports a large downward "disturbance"
that is not there. The force the motor *delivers* is P(min(x, x_max)): the same map, evaluated at
the logged PWM and capped at the motor's maximum P(x_max).

:func:`fit_thrust_map` fits P per vehicle type on TRAIN logs with ``numpy.polynomial`` least squares
on samples where the motors are not saturated (x below the log's ceiling, then a robust refit
without samples whose ``u[N]`` disagrees with their PWM); :func:`saturated_samples` flags samples
where any motor's desired force exceeds what its PWM gives.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.polynomial import Polynomial

from proxplan.fileio import UserError

MIN_R2 = 0.9
"""A thrust map must explain at least this share of the variance of u[N] (on its inliers) to be used, -."""
MIN_INLIER_FRACTION = 0.8
"""At least this share of the unsaturated samples must agree with the map (robust fit) for it to be used, -."""
CEILING_MARGIN_V = 0.05
"""Samples with pwm*Vbat within this of their log's ceiling are left out of the fit, V."""
SATURATION_BAND_V = 0.2
"""A motor can only be saturated with pwm*Vbat within this of the ceiling x_max (the per-log ceilings
of the Neural-Swarm logs spread over ~0.15 V), V."""
OVERSHOOT_REL = 0.1
"""A saturated stretch must hold a desired force this fraction above the motor's maximum, -."""
SATURATION_REL = 0.02
"""A motor is saturated when its desired force exceeds what its PWM delivers by this fraction (or by
5 fit-RMS, whichever is larger), -."""


@dataclass(frozen=True)
class ThrustMap:
    """Per-motor delivered thrust f_N = P(min(x, x_max_V)), x = pwm * Vbat, P a cubic."""

    coef: tuple[float, ...]  # power-basis coefficients c0..c3 of P: N, N/V, N/V^2, N/V^3
    x_max_V: float  # saturation ceiling of pwm * Vbat (largest value seen in the fit logs), V
    rms_N: float  # RMS of u[N] - P(x) on the fitted (unsaturated) samples, N
    n_fit: int  # motor samples used in the fit
    r2: float = 1.0  # share of the variance of u[N] that P explains on the robust fit's inliers, -
    monotonic: bool = True  # P rises over the fitted range up to x_max
    inlier_fraction: float = 1.0  # share of samples below the ceiling kept by the robust refit, -

    @property
    def usable(self) -> bool:
        """A static map exists: P rises and explains >= :data:`MIN_R2` of u[N] (false e.g. for logs
        whose u[N] is the lagged actual thrust and PWM the command), on at least
        :data:`MIN_INLIER_FRACTION` of the samples below the ceiling. The share is taken on the robust
        fit's inliers: the few saturated-but-below-ceiling samples (u[N] up to 10x the motor's maximum)
        must not decide whether the map of all the others holds."""
        return self.monotonic and self.r2 >= MIN_R2 and self.inlier_fraction >= MIN_INLIER_FRACTION

    @property
    def max_thrust_N(self) -> float:
        """What one motor can give: P at the ceiling, N."""
        return float(Polynomial(self.coef)(self.x_max_V))

    def thrust_N(self, pwm: np.ndarray, vbat_V: np.ndarray) -> np.ndarray:
        """Delivered per-motor thrust (N, 4), N, from PWM (N, 4) 0..1 and Vbat (N,) V, capped."""
        x = np.minimum(np.asarray(pwm) * np.asarray(vbat_V)[:, None], self.x_max_V)
        return np.clip(Polynomial(self.coef)(x), 0.0, None)

    def to_dict(self) -> dict[str, Any]:
        return {"coef": [float(c) for c in self.coef], "x_max_V": self.x_max_V, "rms_N": self.rms_N,
                "n_fit": self.n_fit, "r2": self.r2, "monotonic": self.monotonic,
                "inlier_fraction": self.inlier_fraction, "max_thrust_N": self.max_thrust_N}  # fmt: skip

    @staticmethod
    def from_dict(data: Any, where: str) -> ThrustMap:
        """Inverse of :meth:`to_dict`; UserError naming ``where`` on a malformed mapping."""
        try:
            coef = tuple(float(c) for c in data["coef"])
            out = ThrustMap(coef=coef, x_max_V=float(data["x_max_V"]), rms_N=float(data.get("rms_N", 0.0)),
                            n_fit=int(data.get("n_fit", 0)), r2=float(data.get("r2", 1.0)),
                            monotonic=bool(data.get("monotonic", True)),
                             inlier_fraction=float(data.get("inlier_fraction", 1.0)))  # fmt: skip
        except (KeyError, TypeError, ValueError):
            raise UserError(f"{where}: expected a mapping with coef (4 numbers) and x_max_V (V)") from None
        if len(coef) != 4 or not out.x_max_V > 0:
            raise UserError(f"{where}: expected a mapping with coef (4 numbers) and x_max_V (V)")
        return out


@dataclass(frozen=True)
class MotorSamples:
    """One log's motor data: desired force (N, 4) N, PWM (N, 4) 0..1, Vbat (N,) V."""

    commanded_N: np.ndarray
    pwm: np.ndarray
    vbat_V: np.ndarray


def fit_thrust_map(logs: Sequence[MotorSamples], *, max_samples: int = 200_000) -> ThrustMap:
    """Fit P (cubic) on unsaturated samples of ``logs`` (one vehicle type, train flights).

    Unsaturated: pwm*Vbat more than :data:`CEILING_MARGIN_V` below the log's own ceiling; then one
    robust refit drops samples whose residual exceeds 5 robust sigma (a saturated motor's u[N]).
    """
    xs, us, ceilings = [], [], []
    for s in logs:
        x = s.pwm * s.vbat_V[:, None]
        ceiling = float(np.max(x))
        ceilings.append(ceiling)
        ok = x < ceiling - CEILING_MARGIN_V
        xs.append(x[ok])
        us.append(s.commanded_N[ok])
    x, u = np.concatenate(xs), np.concatenate(us)
    if x.size < 20:
        raise UserError("thrust map: fewer than 20 unsaturated motor samples with PWM and Vbat on train flights")
    step = max(1, x.size // max_samples)
    x, u = x[::step], u[::step]
    poly = Polynomial.fit(x, u, 3)
    r = u - poly(x)
    sigma = 1.4826 * float(np.median(np.abs(r - np.median(r))))
    keep = np.abs(r) <= 5.0 * max(sigma, 1e-6)
    poly = Polynomial.fit(x[keep], u[keep], 3)
    rms = float(np.sqrt(np.mean((u[keep] - poly(x[keep])) ** 2)))
    uk = u[keep]
    ss = float(np.sum((uk - uk.mean()) ** 2))
    r2 = 1.0 - float(np.sum((uk - poly(x[keep])) ** 2)) / ss if ss > 0 else 0.0
    coef = tuple(float(c) for c in np.pad(poly.convert().coef, (0, 4))[:4])
    grid = np.linspace(float(np.quantile(x, 0.01)), max(ceilings), 50)
    monotonic = bool(np.all(np.diff(Polynomial(coef)(grid)) > 0.0))
    return ThrustMap(coef=coef, x_max_V=max(ceilings), rms_N=rms, n_fit=int(keep.sum()), r2=r2, monotonic=monotonic,
                     inlier_fraction=float(keep.mean()))  # fmt: skip


def saturated_motors(thrust_map: ThrustMap, s: MotorSamples) -> np.ndarray:
    """(N, 4) bool: the motor is saturated.

    A saturated stretch of one motor is a contiguous run of samples with PWM near its ceiling and the
    desired force above what that PWM delivers (by :data:`SATURATION_REL` or 5 fit-RMS), in which the
    desired force somewhere exceeds the motor's maximum by :data:`OVERSHOOT_REL` — something a force
    the motor really produced never does (so a lagged *actual* thrust, as simulator logs hold, is
    never taken for saturation).
    """
    from_pwm = thrust_map.thrust_N(s.pwm, s.vbat_V)
    tol = np.maximum(SATURATION_REL * from_pwm, 5.0 * thrust_map.rms_N)
    at_ceiling = s.pwm * s.vbat_V[:, None] >= thrust_map.x_max_V - SATURATION_BAND_V
    inconsistent = at_ceiling & (s.commanded_N - from_pwm > tol)
    beyond = s.commanded_N > (1.0 + OVERSHOOT_REL) * thrust_map.max_thrust_N
    out = np.zeros_like(inconsistent)
    for k in range(inconsistent.shape[1]):
        m = inconsistent[:, k]
        if not m.any():
            continue
        run = np.cumsum(np.concatenate([[m[0]], m[1:] & ~m[:-1]]))  # run id (valid where m)
        hit = np.bincount(run[m], weights=beyond[m, k], minlength=run.max() + 1) > 0
        out[:, k] = m & hit[run]
    return out


def saturated_samples(thrust_map: ThrustMap, s: MotorSamples) -> np.ndarray:
    """(N,) bool: some motor is saturated (:func:`saturated_motors`)."""
    return np.any(saturated_motors(thrust_map, s), axis=1)


def delivered_thrust_N(thrust_map: ThrustMap, s: MotorSamples) -> np.ndarray:
    """Per-motor delivered thrust (N, 4), N: the logged u[N] where it agrees with the PWM, and
    P(min(x, x_max)) (the PWM's force, capped at the motor's maximum) where the motor saturates.

    Where u[N] and PWM agree they differ by the map's noise only (RMS ~1 % on the Neural-Swarm logs),
    and u[N] keeps the finer resolution (and, in simulator logs, the motor lag)."""
    sat = saturated_motors(thrust_map, s)
    return np.where(sat, thrust_map.thrust_N(s.pwm, s.vbat_V), s.commanded_N)


def fit_thrust_maps(samples: Mapping[str, Sequence[MotorSamples]]) -> dict[str, ThrustMap]:
    """:func:`fit_thrust_map` per vehicle type (types without PWM logs are left out)."""
    return {t: fit_thrust_map(logs) for t, logs in samples.items() if logs}
