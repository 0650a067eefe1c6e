"""Delivered motor thrust from PWM and battery voltage at both motor limits, per vehicle type.

The Neural-Swarm logs hold, per motor, the firmware's *desired* force ``u[N]`` and the PWM command it
sent (normalised 0..1), plus the battery voltage. The firmware turns a desired force into PWM with a
voltage-compensated static map, so while a motor is inside its range

    u_N = P(x),    x = pwm * Vbat  (V, the mean voltage across the motor)

with P a cubic (the firmware's own thrust map is a polynomial in PWM and Vbat; the Crazyflie 2.0
map of Foerster 2015, eq. 3.3, is a quadratic in PWM at fixed voltage). At both ends of the range the
PWM stops and ``u[N]`` does not:

* **ceiling** — PWM stops at its top (x ~ 3.3 V on a full battery, lower on a low one) while ``u[N]``
  keeps growing (up to ~10x what the motor can give): read as thrust, it makes a false DOWNWARD force;
* **floor** — PWM stops at 0 (the motor is off) while ``u[N]`` goes negative (down to -7 N on the
  Neural-Swarm logs): read as thrust, it makes a false UPWARD force.

The force a motor *delivers* is D(x) = clip(P(clip(x, 0, x_max)), 0, P(x_max)): the same map at the
logged PWM, never below zero nor above the motor's maximum. :func:`motor_limits` flags where a motor
is at a limit (``u[N]`` disagrees with its PWM there), :func:`delivered_thrust_N` puts D(x) there and
keeps ``u[N]`` elsewhere.

:func:`fit_thrust_map` fits P per vehicle type on TRAIN logs with ``numpy.polynomial`` least squares
on samples inside the range (PWM above the floor, x below the log's ceiling), then a robust refit
without samples whose ``u[N]`` disagrees with their PWM.
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
PWM_FLOOR = 1e-3
"""A PWM at or below this (normalised, ~65 of 65536 counts) is the motor switched off: the floor, -."""
SATURATION_REL = 0.02
"""A motor's desired force disagrees with its PWM when they differ by this fraction of the PWM's force
(or by 5 fit-RMS, whichever is larger), -."""
LIMIT_WINDOW_S = 1.0
"""Half-width of the window in which a limit stretch must ask for a force the motor gives nowhere, s."""
FLOOR, IN_RANGE, CEILING = -1, 0, 1
"""Per-motor limit states of :func:`motor_limits`."""


@dataclass(frozen=True)
class ThrustMap:
    """Per-motor delivered thrust f_N = P(clip(x, 0, x_max_V)) within 0..P(x_max_V), x = pwm * Vbat, P a cubic."""

    coef: tuple[float, ...]  # power-basis coefficients c0..c3 of P: N, N/V, N/V^2, N/V^3
    x_max_V: float  # saturation ceiling of pwm * Vbat (largest value seen in the fit logs), V
    rms_N: float  # RMS of u[N] - P(x) on the fitted (unsaturated) samples, N
    n_fit: int  # motor samples used in the fit
    r2: float = 1.0  # share of the variance of u[N] that P explains on the robust fit's inliers, -
    monotonic: bool = True  # P rises over the fitted range up to x_max
    inlier_fraction: float = 1.0  # share of samples below the ceiling kept by the robust refit, -
    source: str = "fitted"  # fitted on logged u[N]; "published:..." / "free-flight-scale:..." (identify.pwm_thrust)
    scale: float = 1.0  # free-flight scale applied to a base / published map (identify.pwm_thrust), -

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
        """Delivered per-motor thrust (N, 4), N, from PWM (N, 4) 0..1 and Vbat (N,) V, within 0..max."""
        return self.thrust_at_N(np.asarray(pwm) * np.asarray(vbat_V)[:, None])

    def thrust_at_N(self, x_V: np.ndarray) -> np.ndarray:
        """Delivered thrust D(x) = P(clip(x, 0, x_max)) within 0..max, N, of x = pwm * Vbat (any shape), V."""
        return np.clip(Polynomial(self.coef)(np.clip(x_V, 0.0, self.x_max_V)), 0.0, self.max_thrust_N)

    def to_dict(self) -> dict[str, Any]:
        return {"coef": [float(c) for c in self.coef], "x_max_V": self.x_max_V, "rms_N": self.rms_N,
                "n_fit": self.n_fit, "r2": self.r2, "monotonic": self.monotonic,
                "inlier_fraction": self.inlier_fraction, "max_thrust_N": self.max_thrust_N,
                "source": self.source, "scale": self.scale}  # fmt: skip

    @staticmethod
    def from_dict(data: Any, where: str) -> ThrustMap:
        """Inverse of :meth:`to_dict`; UserError naming ``where`` on a malformed mapping."""
        try:
            coef = tuple(float(c) for c in data["coef"])
            out = ThrustMap(coef=coef, x_max_V=float(data["x_max_V"]), rms_N=float(data.get("rms_N", 0.0)),
                            n_fit=int(data.get("n_fit", 0)), r2=float(data.get("r2", 1.0)),
                            monotonic=bool(data.get("monotonic", True)),
                             inlier_fraction=float(data.get("inlier_fraction", 1.0)),
                             source=str(data.get("source", "fitted")), scale=float(data.get("scale", 1.0)))  # fmt: skip
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

    Inside the range: PWM above :data:`PWM_FLOOR` and pwm*Vbat more than :data:`CEILING_MARGIN_V` below
    the log's own ceiling; then one robust refit drops samples whose residual exceeds 5 robust sigma
    (a saturated motor's u[N]).
    """
    xs, us, ceilings = [], [], []
    for s in logs:
        x = s.pwm * s.vbat_V[:, None]
        ceiling = float(np.max(x))
        ceilings.append(ceiling)
        ok = (x < ceiling - CEILING_MARGIN_V) & (s.pwm > PWM_FLOOR)
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


def _runs_holding(mask: np.ndarray, hit: np.ndarray) -> np.ndarray:
    """(N,) bool: the samples of every contiguous run of ``mask`` (N,) that holds a ``hit`` (N,)."""
    if not mask.any():
        return mask.copy()
    run = np.cumsum(np.concatenate([[mask[0]], mask[1:] & ~mask[:-1]]))  # run id (valid where mask)
    held = np.bincount(run[mask], weights=hit[mask], minlength=run.max() + 1) > 0
    return mask & held[run]


def motor_limits(thrust_map: ThrustMap, s: MotorSamples, *, dt_s: float = 0.01) -> np.ndarray:
    """(N, 4) int8 per motor: :data:`FLOOR`, :data:`IN_RANGE` or :data:`CEILING`.

    The desired force u disagrees with its PWM where |u - D(x)| exceeds :data:`SATURATION_REL` of D(x)
    (or 5 fit-RMS). A contiguous stretch of one motor's samples with u above D(x) is at the CEILING
    when it holds a u above what the motor delivers at ANY of its PWMs within +-:data:`LIMIT_WINDOW_S`
    (D of the window's highest x, by the same tolerance); a stretch with u below D(x) is at the FLOOR
    when it holds a u below D of the window's lowest x (PWM 0: any negative u). The top of the window
    moves with the battery, so a motor stuck at a low battery's ceiling is found as one at a full
    battery's, without a voltage band. A force the motor gives within the window is never a limit:
    the PWM and u[N] logged a sample apart, or a lagged *actual* thrust (simulator logs, whose u follows
    its PWM late and never leaves the range the PWM spans), are kept as they are. ``dt_s`` is the
    sample time (s) the window is counted in.
    """
    from scipy.ndimage import maximum_filter1d, minimum_filter1d

    u = s.commanded_N
    x = s.pwm * s.vbat_V[:, None]
    from_pwm = thrust_map.thrust_at_N(x)
    size = 2 * max(1, int(round(LIMIT_WINDOW_S / dt_s))) + 1
    top = thrust_map.thrust_at_N(maximum_filter1d(x, size=size, axis=0, mode="nearest"))
    bottom = thrust_map.thrust_at_N(minimum_filter1d(x, size=size, axis=0, mode="nearest"))

    def tol(f: np.ndarray) -> np.ndarray:
        return np.maximum(SATURATION_REL * f, 5.0 * thrust_map.rms_N)

    above, below = u - from_pwm > tol(from_pwm), from_pwm - u > tol(from_pwm)
    ceiling_hit, floor_hit = u - top > tol(top), bottom - u > tol(bottom)
    out = np.zeros(u.shape, dtype=np.int8)
    for k in range(u.shape[1]):
        out[_runs_holding(above[:, k], ceiling_hit[:, k]), k] = CEILING
        out[_runs_holding(below[:, k], floor_hit[:, k]), k] = FLOOR
    return out


def delivered_log_limits(
    limits: np.ndarray, s: MotorSamples, *, min_thrust_N: float, max_thrust_N: float
) -> np.ndarray:
    """(N, 4) int8 per motor: :func:`motor_limits`' ``limits`` of a log whose ``u[N]`` the manifest declares
    DELIVERED (the rotors' force: a simulator's k_eta omega^2, a vehicle with rotor-speed feedback), kept only
    where ``u[N]`` could not be a delivered force.

    Why: on a commanded log a ``u[N]`` that disagrees with its PWM at a limit is a desired force the motor does
    not give, and :func:`delivered_thrust_N` puts the PWM's force there. A delivered ``u[N]`` disagrees with the
    PWM by the motor lag (the PWM is always a command) and by the map's error where the map is an
    extrapolation: a map fitted on hover-range PWM gives D(0) = P(0) and D(x_max) = P(x_max) from its
    polynomial's ends (on a simulator's small quad 0.055 N and 1.02 N per motor, where the motor gives 0 and
    1.15 N). Replacing such a ``u[N]`` put the unlagged, extrapolated command in place of the measured force:
    4-8 g of F_z error on flights whose motors saturate (a hidden yaw torque of 0.05 m x F_z on two small
    quads), which the selection then explained with a lagged share of the downwash. A delivered force is
    bounded by what the motor can give: a limit stretch is kept only when it holds a ``u[N]`` below
    ``min_thrust_N`` or above ``max_thrust_N`` (the vehicle's facts, N) by more than :data:`SATURATION_REL` of
    ``max_thrust_N`` (a desired force in a log declared delivered: a mis-declared log); the motors at a limit
    otherwise are those whose PWM sits at an end of its range (:func:`proxplan.identify.pwm_thrust.pwm_limits`,
    the caller's), their force left as logged."""
    u = s.commanded_N
    tol = SATURATION_REL * max_thrust_N
    out = np.zeros(u.shape, dtype=np.int8)
    for k in range(u.shape[1]):
        out[_runs_holding(limits[:, k] == CEILING, u[:, k] > max_thrust_N + tol), k] = CEILING
        out[_runs_holding(limits[:, k] == FLOOR, u[:, k] < min_thrust_N - tol), k] = FLOOR
    return out


def saturated_motors(thrust_map: ThrustMap, s: MotorSamples) -> np.ndarray:
    """(N, 4) bool: the motor is at a limit, its ceiling or its floor (:func:`motor_limits`)."""
    return motor_limits(thrust_map, s) != IN_RANGE


def saturated_samples(thrust_map: ThrustMap, s: MotorSamples) -> np.ndarray:
    """(N,) bool: some motor is at a limit (:func:`motor_limits`)."""
    return np.any(saturated_motors(thrust_map, s), axis=1)


def delivered_thrust_N(thrust_map: ThrustMap, s: MotorSamples, limits: np.ndarray | None = None) -> np.ndarray:
    """Per-motor delivered thrust (N, 4), N: the logged u[N] where it agrees with the PWM, and
    D(x) = P(clip(x, 0, x_max)) clipped to 0..max (the PWM's force) where the motor is at a limit
    (``limits``: :func:`motor_limits`, computed when not given).

    Where u[N] and PWM agree they differ by the map's noise only (RMS ~1 % on the Neural-Swarm logs),
    and u[N] keeps the finer resolution (and, in simulator logs, the motor lag)."""
    lim = motor_limits(thrust_map, s) if limits is None else limits
    return np.where(lim != IN_RANGE, thrust_map.thrust_N(s.pwm, s.vbat_V), s.commanded_N)


def fit_thrust_maps(samples: Mapping[str, Sequence[MotorSamples]]) -> dict[str, ThrustMap]:
    """:func:`fit_thrust_map` per vehicle type (types without PWM logs are left out)."""
    return {t: fit_thrust_map(logs) for t, logs in samples.items() if logs}
