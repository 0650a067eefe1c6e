"""The measurement checks itself: which motor time constant do the logs say?

(S0-11) F = m R alpha - T z_B needs the thrust the rotors DELIVER. A log of commanded thrust reaches
the air through the motors' first-order lag (``motor_thrust: commanded``; tau =
``Vehicle.motor_time_constant_s``), a log of delivered thrust does not (``motor_thrust: delivered``).
A wrong declaration puts a false lag into every measured force — and the lag then looks like an
aerodynamic effect that follows the motion late (discovery keeps lagged terms on data with no
effect at all).

In free flight (no source overhead within r < 3 L, rotor plane above :data:`FREE_HEIGHT_M`, every
motor inside its range within +-0.2 s) the disturbance is small and steady; the measured F_z varies
there mostly through measurement error, and a wrong lag adds the thrust's rate of change to it. So
:func:`motor_lag_check` measures F_z on the free-flight samples with each tau of :data:`TAU_GRID_S`
(0 = delivered thrust as logged) and takes the tau with the smallest spread (RMS about each log's
mean: a constant thrust error is not a lag). It WARNS when the declaration disagrees: the declared
tau (0 for delivered, the vehicle's for commanded) leaves a spread more than :data:`WARN_EXCESS`
above the best one and lies outside a factor :data:`TAU_FACTOR` of it (or one of them is 0).

**Only the delay is evidence.** A first-order lag both delays the thrust and smooths it; smoothing alone
lowers the spread wherever the logged thrust carries noise the accelerometer did not see (a hovering
vehicle with command noise), which is no evidence of a lag (issue 35: a rightly declared log drew a
warning). So each candidate lag is applied as an ALL-PASS with the lag's phase, -atan(omega tau), and
magnitude 1 (:func:`phase_of_lag`): every candidate keeps the noise's power, and only a thrust that
reaches the air late makes one tau steadier than another.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from proxplan.identify.measure import FREE_HEIGHT_M, MeasureOptions, measure_log
from proxplan.identify.vehicle_log import VehicleLog
from proxplan.physics import Vehicle

TAU_GRID_S = (0.0, 0.02, 0.035, 0.05, 0.072, 0.09, 0.11, 0.14, 0.18, 0.25)
"""Motor time constants tried, s (0: the logged thrust is what the rotors deliver)."""
WARN_EXCESS = 0.05
"""Warn when the declared tau's spread exceeds the best one's by more than this fraction, -."""
TAU_FACTOR = 2.0
"""... and the declared tau lies outside this factor of the best one (or exactly one of them is 0), -."""
MIN_FREE_SAMPLES = 200
"""Fewer free-flight samples of a type than this: no verdict for it."""


@dataclass(frozen=True)
class LagSample:
    """One vehicle log for the check: its vehicle, cleaned log with the thrust as the measurement
    takes it BEFORE any lag (delivered at the motor limits), and its free-flight samples (N,) bool."""

    vehicle_type: str
    vehicle: Vehicle
    log: VehicleLog
    free: np.ndarray
    flight: str = ""  # the flight the log belongs to (the unit a check resamples)


def motor_lag_check(
    samples: Sequence[LagSample],
    *,
    motor_thrust: str,
    options: MeasureOptions,
    declared_tau_s: Mapping[str, float] | None = None,
) -> dict[str, Any]:
    """Per vehicle type: the spread of free-flight F_z (N) per tau of :data:`TAU_GRID_S`, the best tau
    (s), the declared one (s) and ``warning`` (text, or None); plus ``warnings`` (list) over all types.

    ``declared_tau_s`` maps a type to the tau the measurement uses (default: the vehicle's own for
    ``commanded``, 0 for ``delivered``)."""
    out: dict[str, Any] = {"tau_grid_s": list(TAU_GRID_S), "motor_thrust": motor_thrust, "types": {}, "warnings": []}
    by_type: dict[str, list[LagSample]] = {}
    for s in samples:
        if s.free.sum() > 10:
            by_type.setdefault(s.vehicle_type, []).append(s)
    for vtype, group in sorted(by_type.items()):
        veh = group[0].vehicle
        if declared_tau_s is not None and vtype in declared_tau_s:
            declared = float(declared_tau_s[vtype])
        else:
            declared = veh.motor_time_constant_s if motor_thrust == "commanded" else 0.0
        n_free = int(sum(s.free.sum() for s in group))
        grid = sorted(set(TAU_GRID_S) | {round(declared, 6)})
        spread = [_spread(group, tau, options) for tau in grid]
        k = int(np.argmin(spread))
        best, s_best = grid[k], spread[k]
        s_decl = spread[grid.index(round(declared, 6))]
        entry: dict[str, Any] = {"declared_tau_s": declared, "best_tau_s": best, "n_free_samples": n_free,
                                 "spread_N": dict(zip((f"{t:g}" for t in grid), spread)),
                                 "spread_declared_N": s_decl, "spread_best_N": s_best, "warning": None}  # fmt: skip
        if n_free >= MIN_FREE_SAMPLES and _disagrees(declared, best, s_decl, s_best):
            reads = "delivered" if best == 0.0 else f"commanded with a motor lag near {best:g} s"
            entry["warning"] = (
                f"{vtype}: the manifest says motor_thrust: {motor_thrust} (motor lag {declared:g} s), but the "
                f"free-flight force is steadiest with a lag of {best:g} s (spread {1000 * s_best:.2f} mN against "
                f"{1000 * s_decl:.2f} mN): the logs look {reads}; check motor_thrust (a false lag shows up as "
                "a lagged 'effect')"
            )
            out["warnings"].append(entry["warning"])
        out["types"][vtype] = entry
    return out


def _disagrees(declared: float, best: float, s_decl: float, s_best: float) -> bool:
    if s_decl <= (1.0 + WARN_EXCESS) * s_best:
        return False
    if (declared == 0.0) != (best == 0.0):
        return True
    return declared > 0.0 and not (best / TAU_FACTOR <= declared <= best * TAU_FACTOR)


def phase_of_lag(x: np.ndarray, dt_s: float, tau_s: float) -> np.ndarray:
    """``x`` (N, k), one contiguous segment sampled every ``dt_s`` (s), through an all-pass with the phase of a
    first-order lag of time constant ``tau_s`` (s): H(omega) = exp(-i atan(omega tau)), |H| = 1 (zero-padded
    FFT, about the segment's mean)."""
    if tau_s <= 0.0 or len(x) < 4:
        return x
    n = len(x)
    mean = x.mean(axis=0)
    spec = np.fft.rfft(x - mean, 2 * n, axis=0)
    omega = 2.0 * np.pi * np.fft.rfftfreq(2 * n, dt_s)
    out = np.fft.irfft(spec * np.exp(-1j * np.arctan(omega * tau_s))[:, None], 2 * n, axis=0)[:n]
    return out + mean


def _delayed(log: VehicleLog, tau_s: float) -> VehicleLog:
    """``log`` with every contiguous segment's motor thrust through :func:`phase_of_lag`."""
    if tau_s <= 0.0:
        return log
    thrust = log.motor_thrust_N.copy()
    seg = np.zeros(len(log), dtype=int) if log.segment is None else np.asarray(log.segment)
    for sid in np.unique(seg):
        idx = np.flatnonzero(seg == sid)
        dt = float(np.median(np.diff(log.t_s[idx]))) if len(idx) > 1 else 0.01
        thrust[idx] = phase_of_lag(thrust[idx], dt, tau_s)
    return replace(log, motor_thrust_N=thrust)


def _spread(group: Sequence[LagSample], tau_s: float, options: MeasureOptions) -> float:
    """RMS of free-flight F_z about each log's free-flight mean, pooled over ``group``, N, the thrust taken
    with the phase of a lag ``tau_s`` (module docstring)."""
    opts = replace(options, motor_time_constant_s=None, thrust_scale=1.0)
    sse, n = 0.0, 0
    for s in group:
        fz = measure_log(s.vehicle, _delayed(s.log, tau_s), options=opts).force_N[s.free, 2]
        sse += float(np.sum((fz - fz.mean()) ** 2))
        n += fz.size
    return float(np.sqrt(sse / n)) if n else float("nan")


def check_loaded(data: Any, *, motor_thrust: str, options: MeasureOptions) -> dict[str, Any]:
    """:func:`motor_lag_check` on the train and validation flights of a
    :class:`proxplan.identify.loading.LoadedData` (every flight when it has none), with the tau the
    measurement used per type (:func:`proxplan.identify.loading.measure_options_for`)."""
    from proxplan.identify.loading import measure_options_for

    declared = {t: measure_options_for(options, v, motor_thrust).motor_time_constant_s or 0.0
                for t, v in data.types.items()}  # fmt: skip
    return motor_lag_check(lag_samples(data), motor_thrust=motor_thrust, options=options, declared_tau_s=declared)


def lag_samples(data: Any, *, splits: Sequence[str] = ("train", "validation"), alone: bool = False) -> list[LagSample]:
    """The :class:`LagSample` of every scored vehicle of ``data`` (a
    :class:`proxplan.identify.loading.LoadedData`) on flights of ``splits`` (all its flights when none is):
    free flight = no source overhead within r < 3 L, above :data:`FREE_HEIGHT_M`, every motor in range
    (:func:`proxplan.identify.strata.authority_masks`); ``alone``: also no neighbour beside or below within the
    same reach (:func:`proxplan.identify.data.neighbours_near`), so that no neighbour's air, modelled or not, is
    in the samples."""
    from proxplan.identify.data import neighbours_near, sources_overhead
    from proxplan.identify.strata import authority_masks

    units = [u for u in data.units if u.scored and len(u) and (u.flight, u.name) in data.logs]
    if any(u.split in splits for u in units):
        units = [u for u in units if u.split in splits]
    out = []
    for u in units:
        veh, log = data.logs[(u.flight, u.name)]
        free = (
            (sources_overhead(u, data.types)[0] == 0)
            & (u.height_above_ground_m > FREE_HEIGHT_M)
            & authority_masks(u, data.types)["in_range"]
        )
        if alone:
            free &= ~neighbours_near(u, data.types)
        out.append(LagSample(u.type, veh, log, free, u.flight))
    return out
