"""How does the logged motor command run between two samples? Chosen per vehicle type from free flight.

A log holds the motor command at its own rate (100 Hz for the Crazyflie logs), while the controller
writes it faster (500 Hz on a Crazyflie). The motor lag (:func:`proxplan.identify.measure.motor_lag_compensated_N`)
needs the command between samples: held from each sample to the next (zero-order hold, p = 0, the exact
inverse of a command written once per log sample) or running linearly to the next sample (first-order hold,
p = 1, closer for a command written several times per sample). Which one is right is a property of the
log source, not of the aerodynamics, and a wrong one is a measurement error that identify would
otherwise meet as an effect: the roll and pitch torque of (S0-13, S0-14) are motor DIFFERENCES, changing
faster than the sum, and a hold half a sample late leaves them a residual that tracks the vehicle's
own angular acceleration (issue 35, round 35Z: the flown clean sets' kept terms).

**The check.** In free flight (the samples of :func:`proxplan.identify.motor_check.lag_samples`: no source
overhead, out of ground effect, every motor in range) the disturbance is small and steady, so the
measured wrench varies there mostly by measurement error. For each candidate p of :data:`HOLDS` and each
channel c of F_z, tau_x, tau_y (world frame), the spread of each FLIGHT's free-flight samples about their
mean is compared with p = 0's as d_fc = 0.5 ln(SSE_p / SSE_0) (per flight, so the flight is the unit that is
resampled: samples of one flight are not independent). Over the n flights of the type, d_c's mean and
standard error give t_c = mean / se. A candidate is **admissible** when no channel is worse beyond chance
(t_c <= q) and at least one is better beyond it (t_c < -q), q the one-sided Student-t quantile of
:data:`ALPHA` with n - 1 degrees of freedom; the admissible candidate with the smallest mean of d over the
channels is taken, and p = 0 (the declared, exact inverse of a once-per-sample command) otherwise. No
constant here was set while watching a result: ALPHA is the conventional one-sided 2.5 % level (the
chance that a p with no effect on any channel is taken is at most about 3 x 2.5 %), :data:`MIN_FLIGHTS`
the fewest flights with which a standard error has at least two degrees of freedom.

Logs of DELIVERED thrust pass through no lag, so there is nothing to choose (p = 0, reported as such).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from scipy.stats import t as student_t

from proxplan.identify.measure import MeasureOptions, measure_log
from proxplan.identify.motor_check import LagSample, lag_samples

__all__ = ["ALPHA", "HOLDS", "MIN_FLIGHTS", "CommandHold", "command_hold_check", "check_loaded_holds"]

HOLDS = (0.0, 0.5, 1.0)
"""Candidate command interpolations p, -: 0 held to the next sample, 1 linear to it."""
ALPHA = 0.025
"""One-sided level of each channel's test (worse / better beyond chance), -."""
MIN_FLIGHTS = 3
"""Fewer flights with free-flight samples of a type than this: no verdict, p = 0 kept."""
NUMERICAL_ZERO = 1e-9
"""A channel whose free-flight spread is below this (N or N m) at p = 0 holds nothing to judge (a simulated
vehicle whose motors always turn together has no roll or pitch torque): left out of the test."""
MIN_FREE_SAMPLES = 20
"""A log with fewer free-flight samples than this adds nothing to its flight's spread."""
CHANNELS = ("F_z", "tau_x", "tau_y")


@dataclass(frozen=True)
class CommandHold:
    """The choice for one vehicle type: ``interpolation`` p (-), why, and the evidence.

    ``spread`` maps each candidate p (as text) to each channel's pooled free-flight spread (F_z in N, torques in
    N m); ``t_stat`` maps each candidate p > 0 to each channel's t of d = 0.5 ln(SSE_p / SSE_0) over flights."""

    vehicle_type: str
    interpolation: float
    reason: str
    n_flights: int
    spread: dict[str, dict[str, float]] = field(default_factory=dict)
    t_stat: dict[str, dict[str, float]] = field(default_factory=dict)
    mean_log_ratio: dict[str, dict[str, float]] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {"interpolation": self.interpolation, "reason": self.reason, "n_flights": self.n_flights,
                "spread": self.spread, "t_stat": self.t_stat, "mean_log_ratio": self.mean_log_ratio}  # fmt: skip


def _flight_sse(group: Sequence[LagSample], options_of, p: float) -> dict[str, np.ndarray]:
    """Per flight: (3,) sums of squares of F_z, tau_x, tau_y about each log's free-flight mean, and counts."""
    out: dict[str, np.ndarray] = {}
    for s in group:
        if s.free.sum() < MIN_FREE_SAMPLES:
            continue
        w = measure_log(s.vehicle, s.log, options=replace(options_of(s), command_interpolation=p))
        x = np.column_stack([w.force_N[s.free, 2], w.torque_Nm[s.free, 0], w.torque_Nm[s.free, 1]])
        acc = out.setdefault(s.flight, np.zeros(4))
        acc[:3] += np.sum((x - x.mean(axis=0)) ** 2, axis=0)
        acc[3] += len(x)
    return out


def _choose(vtype: str, group: Sequence[LagSample], options_of) -> CommandHold:
    sse = {p: _flight_sse(group, options_of, p) for p in HOLDS}
    flights = sorted(sse[0.0])
    n = len(flights)
    spread = {f"{p:g}": dict(zip(CHANNELS, np.sqrt(sum(sse[p][f][:3] for f in flights) / max(sum(sse[p][f][3] for f in flights), 1)).tolist()))
              for p in HOLDS} if n else {}  # fmt: skip
    if n < MIN_FLIGHTS:
        return CommandHold(vtype, 0.0, f"{n} flight(s) with free flight, fewer than {MIN_FLIGHTS}: held (p = 0) kept",
                           n, spread)  # fmt: skip
    q = float(student_t.ppf(1.0 - ALPHA, n - 1))
    t_stat: dict[str, dict[str, float]] = {}
    means: dict[str, dict[str, float]] = {}
    admissible: list[tuple[float, float]] = []
    for p in HOLDS[1:]:
        d = np.array([0.5 * np.log(sse[p][f][:3] / sse[0.0][f][:3]) for f in flights])  # (n, 3)
        mean = d.mean(axis=0)
        se = d.std(axis=0, ddof=1) / np.sqrt(n)
        live = np.array([spread["0"][c] >= NUMERICAL_ZERO for c in CHANNELS])
        t = np.where(live & (se > 0), mean / np.where(se > 0, se, 1.0), 0.0)
        t_stat[f"{p:g}"] = dict(zip(CHANNELS, t.tolist()))
        means[f"{p:g}"] = dict(zip(CHANNELS, mean.tolist()))
        if np.all(t <= q) and np.any(t < -q):
            admissible.append((float(mean.mean()), p))
    if not admissible:
        return CommandHold(vtype, 0.0, f"no interpolation steadier on one channel without being worse on another "
                           f"(one-sided {ALPHA:g} level over {n} flights): held (p = 0) kept", n, spread, t_stat, means)  # fmt: skip
    _, best = min(admissible)
    return CommandHold(vtype, best, f"p = {best:g} steadier in free flight beyond chance on a channel and worse on "
                       f"none (one-sided {ALPHA:g} level over {n} flights)", n, spread, t_stat, means)  # fmt: skip


def command_hold_check(samples: Sequence[LagSample], *, options_of) -> dict[str, CommandHold]:
    """Per vehicle type of ``samples``: the :class:`CommandHold` chosen (module docstring). ``options_of`` gives
    each sample's measurement options (the motor lag it uses)."""
    by_type: dict[str, list[LagSample]] = {}
    for s in samples:
        by_type.setdefault(s.vehicle_type, []).append(s)
    out = {}
    for vtype, group in sorted(by_type.items()):
        if not options_of(group[0]).motor_time_constant_s:
            out[vtype] = CommandHold(vtype, 0.0, "thrust taken as delivered: no motor lag, nothing to choose", 0)
        else:
            out[vtype] = _choose(vtype, group, options_of)
    return out


def check_loaded_holds(data: Any, *, motor_thrust: str, options: MeasureOptions) -> dict[str, CommandHold]:
    """:func:`command_hold_check` on the train and validation flights of a
    :class:`proxplan.identify.loading.LoadedData` (every flight when it has none)."""
    from proxplan.identify.loading import measure_options_for

    return command_hold_check(
        lag_samples(data), options_of=lambda s: measure_options_for(options, s.vehicle, motor_thrust)
    )
