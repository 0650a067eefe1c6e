"""How does the logged motor command run between two samples? Chosen once per log source from free flight.

A log holds the motor command at its own rate (100 Hz for the Crazyflie logs), while the controller
writes it faster (500 Hz on a Crazyflie). The motor lag (:func:`proxplan.identify.measure.motor_lag_compensated_N`)
needs the command between samples: held from each sample to the next (zero-order hold, p = 0, the exact
inverse of a command written once per log sample) or running linearly to the next sample (first-order hold,
p = 1, closer for a command written several times per sample). Which one is right is a property of the
log source, not of the aerodynamics, and a wrong one is a measurement error that identify would
otherwise meet as an effect: the roll and pitch torque of (S0-13, S0-14) are motor DIFFERENCES, changing
faster than the sum, and a hold half a sample late leaves them a residual that tracks the vehicle's
own angular acceleration (issue 35, round 35Z: the flown clean sets' kept terms).

**The check.** In free flight, flown ALONE (the samples of :func:`proxplan.identify.motor_check.lag_samples` with
``alone``: no source overhead, no neighbour beside or below within the same reach, out of ground effect, every
motor in range) the disturbance is small and steady, so the measured wrench varies there mostly by measurement
error. For each candidate p of :data:`HOLDS` and each channel c of F_z, tau_x, tau_y (world frame), the spread of
each FLIGHT's free-flight samples about their mean is compared with p = 0's as d_fc = 0.5 ln(SSE_p / SSE_0) (per
flight, so the flight is the unit that is resampled: samples of one flight are not independent; a flight with
vehicles of several types takes the mean of their log ratios). Over the n flights, d_c's mean and standard error
give t_c = mean / se. A candidate is **admissible** when no channel is worse beyond chance
(t_c <= q) and at least one is better beyond it (t_c < -q), q the one-sided Student-t quantile of
ALPHA / m with n - 1 degrees of freedom, m = (candidates) x (channels) the tests the source gets (Bonferroni):
where no p changes anything, the chance that any candidate is taken is then at most :data:`ALPHA`.
The admissible candidate with the smallest mean of d over the channels is taken, and p = 0 (the declared,
exact inverse of a once-per-sample command) otherwise. ALPHA is the conventional one-sided 2.5 % level,
:data:`MIN_FLIGHTS` the fewest flights with which a standard error has at least two degrees of freedom.
(A first version tested each channel at ALPHA alone; its family-wise chance of a false switch is up to
6 x 2.5 % per type, and on the scripted world's block 39000, whose commands are the exact held inverse, it
switched a type in 4 of 20 draws: the correction restores the level the rule was meant to have.)

Why ONE choice for the log source, not one per vehicle type: the hold is the logger's (how often the firmware
writes the command, how often the log samples it), the same for every vehicle a manifest's logs come from (one
format, one ``motor_thrust``), and a choice per type splits the evidence and lets a type's own aerodynamics,
not its logger, decide (stop 80 shipped a Crazyflie 2.1 held and a Parrot, the same firmware, at p = 0.5).

Why alone, not only free of a source overhead: an effect beside or below a vehicle acts in "free" samples, and a
wrench that varies with the neighbours is judged there as measurement error; the same logger then got different
holds on a set and on its twin without the effect (stop 80, flown bench block 90000: 6 of 10 commanded draws),
which compares two different measurements. The hold is the logger's, so it is chosen where no neighbour is near.

Logs of DELIVERED thrust pass through no lag, so there is nothing to choose (p = 0, reported as such).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from scipy.stats import t as student_t

from proxplan.identify.measure import MeasureOptions, measure_log, motor_lag_compensated_N
from proxplan.identify.motor_check import LagSample, lag_samples
from proxplan.identify.vehicle_log import VehicleLog

__all__ = [
    "ALPHA",
    "HOLDS",
    "MIN_FLIGHTS",
    "CommandHold",
    "check_loaded_holds",
    "command_hold_check",
    "measured_with_holds",
    "phase_of_hold",
]

HOLDS = (0.0, 0.5, 1.0)
"""Candidate command interpolations p, -: 0 held to the next sample, 1 linear to it."""
ALPHA = 0.025
"""Family-wise one-sided level per log source, -: each of its (candidates x channels) tests runs at ALPHA / that
number (Bonferroni)."""
MIN_FLIGHTS = 3
"""Fewer flights with free-flight samples than this: no verdict, p = 0 kept."""
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


def phase_of_hold(x: np.ndarray, dt_s: float, tau_s: float, p: float) -> np.ndarray:
    """``x`` (N, k), the lagged thrust of ONE contiguous segment sampled every ``dt_s`` (s) as the held command
    (p = 0) gives it, moved to the timing of interpolation ``p``: an all-pass (|H| = 1; a circular FFT about the segment's
    mean, so that it keeps the segment's power exactly) with the phase of H_p / H_0,
    H_p(z) = (p c + ((1 - a) - p c) z^-1) / (1 - a z^-1) the lag's discretisation (:func:`proxplan.identify.measure.motor_lag_compensated_N`; a = exp(-dt/tau),
    c = 1 - (1 - a) tau / dt). Interpolating also averages neighbouring samples, which lowers the spread of any
    command noise whatever the timing; the all-pass keeps the noise's power, so only timing is evidence (as
    the motor-lag check does, :func:`proxplan.identify.motor_check.phase_of_lag`). Circular, not zero-padded: a
    padded all-pass spills part of the segment's energy past its end, a loss (0.1 % on 1000 samples of white
    noise) that would make every p > 0 look steadier where noise dominates; wrapping the segment's end onto its
    start instead adds a little at the edges, which can only favour the held command. The Nyquist bin, real for
    an even length, keeps its phase."""
    if p == 0.0 or len(x) < 4:
        return x
    n = len(x)
    a = float(np.exp(-dt_s / tau_s))
    c = 1.0 - (1.0 - a) * tau_s / dt_s
    mean = x.mean(axis=0)
    spec = np.fft.rfft(x - mean, n, axis=0)
    z1 = np.exp(-1j * 2.0 * np.pi * np.fft.rfftfreq(n, dt_s) * dt_s)  # z^-1 on the unit circle
    phase = np.angle(p * c + ((1.0 - a) - p * c) * z1) - np.angle((1.0 - a) * z1)
    if n % 2 == 0:
        phase[-1] = 0.0
    return np.fft.irfft(spec * np.exp(1j * phase)[:, None], n, axis=0) + mean


def _held_then_timed(log: VehicleLog, tau_s: float, p: float) -> VehicleLog:
    """``log`` with its commanded thrust through the motor lag (held command) and then :func:`phase_of_hold`, per
    contiguous segment: measured with no further lag."""
    thrust = np.array(log.motor_thrust_N, dtype=float, copy=True)
    seg = np.zeros(len(log), dtype=int) if log.segment is None else np.asarray(log.segment)
    for sid in np.unique(seg):
        idx = np.flatnonzero(seg == sid)
        dt = float(np.median(np.diff(log.t_s[idx]))) if len(idx) > 1 else 0.01
        thrust[idx] = phase_of_hold(motor_lag_compensated_N(thrust[idx], dt, tau_s), dt, tau_s, p)
    return replace(log, motor_thrust_N=thrust)


def _log_sse(group: Sequence[LagSample], options_of, p: float) -> dict[tuple[str, str], np.ndarray]:
    """Per (flight, vehicle type): (3,) sums of squares of F_z, tau_x, tau_y about each log's free-flight mean, and
    the count, the command's timing that of interpolation ``p`` (:func:`phase_of_hold`)."""
    out: dict[tuple[str, str], np.ndarray] = {}
    for s in group:
        if s.free.sum() < MIN_FREE_SAMPLES:
            continue
        opts = options_of(s)
        tau = float(opts.motor_time_constant_s or 0.0)
        log = _held_then_timed(s.log, tau, p)
        w = measure_log(s.vehicle, log, options=replace(opts, motor_time_constant_s=None, thrust_scale=1.0))
        x = np.column_stack([w.force_N[s.free, 2], w.torque_Nm[s.free, 0], w.torque_Nm[s.free, 1]])
        acc = out.setdefault((s.flight, s.vehicle_type), np.zeros(4))
        acc[:3] += np.sum((x - x.mean(axis=0)) ** 2, axis=0)
        acc[3] += len(x)
    return out


def _spreads(sse: dict[float, dict[tuple[str, str], np.ndarray]], vtype: str) -> dict[str, dict[str, float]]:
    """Each candidate's pooled free-flight spread of type ``vtype`` per channel (N, N m)."""
    keys = [k for k in sse[0.0] if k[1] == vtype]
    if not keys:
        return {}
    return {f"{p:g}": dict(zip(CHANNELS, np.sqrt(sum(sse[p][k][:3] for k in keys) / max(sum(sse[p][k][3] for k in keys), 1)).tolist()))
            for p in HOLDS}  # fmt: skip


def _choose(group: Sequence[LagSample], options_of) -> tuple[CommandHold, dict[str, dict[str, dict[str, float]]]]:
    """The one hold of the log source, and each type's spreads (:func:`_spreads`): ``group`` holds every commanded vehicle of it, of any type. Per flight, d of
    each channel is the mean over the flight's vehicle types of 0.5 ln(SSE_p / SSE_0) (each type's log ratio, so a
    heavy vehicle's larger wrench does not outvote a light one's); a channel numerically silent for a type is left
    out of that type's share (module docstring)."""
    types = sorted({s.vehicle_type for s in group})
    label = " + ".join(types)
    sse = {p: _log_sse(group, options_of, p) for p in HOLDS}
    flights = sorted({f for f, _ in sse[0.0]})
    n = len(flights)
    spread = {t: _spreads(sse, t) for t in types}
    if n < MIN_FLIGHTS:
        return CommandHold(label, 0.0, f"{n} flight(s) with free flight, fewer than {MIN_FLIGHTS}: held (p = 0) kept",
                           n), spread  # fmt: skip
    q = float(student_t.ppf(1.0 - ALPHA / ((len(HOLDS) - 1) * len(CHANNELS)), n - 1))  # Bonferroni (module doc)
    live_of = {t: np.array([bool(spread[t]) and spread[t]["0"][c] >= NUMERICAL_ZERO for c in CHANNELS]) for t in types}
    t_stat: dict[str, dict[str, float]] = {}
    means: dict[str, dict[str, float]] = {}
    admissible: list[tuple[float, float]] = []
    for p in HOLDS[1:]:
        d = np.zeros((n, len(CHANNELS)))
        live = np.zeros(len(CHANNELS), dtype=bool)
        for i, f in enumerate(flights):
            with np.errstate(divide="ignore", invalid="ignore"):
                per = [(0.5 * np.log(sse[p][k][:3] / sse[0.0][k][:3]), live_of[k[1]]) for k in sse[0.0] if k[0] == f]
            num = sum(np.where(lv, r, 0.0) for r, lv in per)
            cnt = sum(lv.astype(float) for _, lv in per)
            d[i] = np.where(cnt > 0, num / np.maximum(cnt, 1.0), 0.0)
            live |= cnt > 0
        mean = d.mean(axis=0)
        se = d.std(axis=0, ddof=1) / np.sqrt(n)
        t = np.where(live & (se > 0), mean / np.where(se > 0, se, 1.0), 0.0)
        t_stat[f"{p:g}"] = dict(zip(CHANNELS, t.tolist()))
        means[f"{p:g}"] = dict(zip(CHANNELS, mean.tolist()))
        if np.all(t <= q) and np.any(t < -q):
            admissible.append((float(mean[live].mean()), p))
    pooled = f"{len(types)} vehicle type(s) of the log source pooled" if len(types) > 1 else "one vehicle type"
    if not admissible:
        return CommandHold(label, 0.0, f"no interpolation steadier on one channel without being worse on another "
                           f"(family-wise one-sided {ALPHA:g} level over {n} flights, {pooled}): held (p = 0) kept",
                           n, {}, t_stat, means), spread  # fmt: skip
    _, best = min(admissible)
    return CommandHold(label, best, f"p = {best:g} steadier in free flight beyond chance on a channel and worse on "
                       f"none (family-wise one-sided {ALPHA:g} level over {n} flights, {pooled})", n, {}, t_stat,
                       means), spread  # fmt: skip


def command_hold_check(samples: Sequence[LagSample], *, options_of) -> dict[str, CommandHold]:
    """Per vehicle type of ``samples``: the :class:`CommandHold` of its log source (module docstring): ONE choice
    for every type whose logs hold commands (the hold is the logger's, and a manifest is one log source: one
    format, one ``motor_thrust``), each type's entry carrying the shared verdict and its own spreads; a type of
    delivered thrust has nothing to choose. ``options_of`` gives each sample's measurement options (the motor lag
    it uses)."""
    types = sorted({s.vehicle_type for s in samples})
    lagged = [s for s in samples if options_of(s).motor_time_constant_s]
    lagged_types = {s.vehicle_type for s in lagged}
    out = {t: CommandHold(t, 0.0, "thrust taken as delivered: no motor lag, nothing to choose", 0)
           for t in types if t not in lagged_types}  # fmt: skip
    if lagged:
        hold, spread = _choose(lagged, options_of)
        for t in sorted(lagged_types):
            out[t] = replace(hold, vehicle_type=t, spread=spread.get(t, {}))
    return dict(sorted(out.items()))


def check_loaded_holds(data: Any, *, motor_thrust: str, options: MeasureOptions) -> dict[str, CommandHold]:
    """:func:`command_hold_check` on the train and validation flights of a
    :class:`proxplan.identify.loading.LoadedData` (every flight when it has none)."""
    from proxplan.identify.loading import measure_options_for

    return command_hold_check(
        lag_samples(data, alone=True), options_of=lambda s: measure_options_for(options, s.vehicle, motor_thrust)
    )


def measured_with_holds(manifest: Any, options: Any, data: Any) -> tuple[Any, Any, dict[str, CommandHold]]:
    """identify's stage: the hold of each type chosen on ``data`` (a :class:`proxplan.identify.loading.LoadedData` of
    ``manifest`` measured with ``options``, an :class:`proxplan.identify.data.IdentifyOptions`), and, where one is
    not held, the options with the choice and the flights measured again with it (the thrust maps as fitted
    already), with a note per such type. Options that already name the holds are kept, with no check."""
    from proxplan.identify.loading import load_units

    if options.measure.command_interpolation_by_type:
        return options, data, {}
    holds = check_loaded_holds(data, motor_thrust=manifest.motor_thrust, options=options.measure)
    chosen = tuple((t, h.interpolation) for t, h in holds.items() if h.interpolation != 0.0)
    if not chosen:
        return options, data, holds
    options = replace(options, measure=replace(options.measure, command_interpolation_by_type=chosen))
    data = load_units(manifest, options=options, thrust_maps=data.thrust_maps)
    data.notes.extend(
        f"{t}: the logged motor command enters the motor lag interpolated between log samples (p = {p:g}; "
        "the free-flight wrench is steadier so: identify.command_check)"
        for t, p in chosen
    )
    return options, data, holds
