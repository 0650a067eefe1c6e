"""Quality checks of one vehicle's flight log: nothing bad passes silently.

:func:`check_log` drops NaN rows, splits a log at gaps, drops short segments, ground contact, idle motors
and the samples near a ground impact (:func:`impact_guard`), and counts each in :class:`Exclusions`; time
going backwards is a :class:`proxplan.fileio.UserError` naming the file and the row. The flight-level
check (vehicles overlapping in time) is :func:`proxplan.identify.flightlog.load_flight`'s.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from proxplan.fileio import UserError
from proxplan.identify.measure import motor_lag_compensated_N
from proxplan.identify.vehicle_log import VehicleLog


@dataclass(frozen=True)
class QualityOptions:
    """Thresholds of the log quality checks."""

    max_gap_s: float = 0.05  # a time step longer than this splits the log into segments, s
    min_segment_s: float = 0.5  # shorter segments are dropped (too short for derivatives), s
    ground_clearance_m: float = 0.03  # samples closer to the ground are ground contact, m
    min_thrust_fraction: float = 0.3  # total motor thrust below this x weight: motors idle/ground, -
    min_overlap_s: float = 1.0  # vehicles of a flight must share at least this much time, s
    impact_speed_mps: float = 0.3  # a ground contact entered descending faster than this is an impact, m/s
    impact_guard_s: float = 0.1  # samples this close (in time) to an impact are excluded too, s


@dataclass(frozen=True)
class Exclusions:
    """Counts of samples excluded by each quality check (reported, never silent)."""

    nan_rows: int = 0
    gap_segments: int = 0  # number of gaps found (each splits the log)
    short_segment_samples: int = 0
    ground_samples: int = 0
    outside_overlap_samples: int = 0
    impact_samples: int = 0  # airborne samples within impact_guard_s of a ground impact
    impacts: int = 0  # ground contacts entered faster than impact_speed_mps (counted, not samples)

    def total(self) -> int:
        return (self.nan_rows + self.short_segment_samples + self.ground_samples + self.outside_overlap_samples
                + self.impact_samples)  # fmt: skip

    def __add__(self, other: Exclusions) -> Exclusions:
        return Exclusions(*(a + b for a, b in zip(_fields(self), _fields(other))))

    def to_dict(self) -> dict[str, int]:
        return dict(zip(_FIELD_NAMES, _fields(self)))


_FIELD_NAMES = ("nan_rows", "gap_segments", "short_segment_samples", "ground_samples", "outside_overlap_samples",
                "impact_samples", "impacts")  # fmt: skip


def _fields(e: Exclusions) -> tuple[int, ...]:
    return tuple(getattr(e, k) for k in _FIELD_NAMES)


def impact_guard(
    t_s: np.ndarray, v_z_mps: np.ndarray, on_ground: np.ndarray, options: QualityOptions
) -> tuple[np.ndarray, int]:
    """Samples near a ground IMPACT (N,) bool, and the number of impacts.

    An impact is a ground contact (``on_ground`` (N,) bool, a run of it) entered descending faster than
    ``options.impact_speed_mps`` (m/s, world z up: ``v_z_mps`` (N,)) at some time within
    ``options.impact_guard_s`` before it. The samples within ``impact_guard_s`` before its first and
    after its last contact sample are guarded: the contact's force reaches them through the
    motion-capture latency and the measurement's smoothing window, and a bounce must not be smoothed
    into the flight around it. Slow touch-downs and take-offs are no impacts (nothing guarded).
    """
    n = len(t_s)
    guard = np.zeros(n, dtype=bool)
    if n == 0 or not on_ground.any():
        return guard, 0
    edges = np.diff(np.concatenate([[0], on_ground.astype(np.int8), [0]]))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)  # runs [start, stop)
    impacts = 0
    for a, b in zip(starts, stops):
        if a == 0:
            continue  # the log starts on the ground: a take-off
        before = (t_s >= t_s[a] - options.impact_guard_s) & (np.arange(n) < a)
        if not np.any(v_z_mps[before] < -options.impact_speed_mps):
            continue
        impacts += 1
        guard |= before
        guard |= (np.arange(n) >= b) & (t_s <= t_s[b - 1] + options.impact_guard_s)
    return guard, impacts


def _idle_motors(log: VehicleLog, idle_N: float, motor_time_constant_s: float | None) -> np.ndarray:
    """(N,) bool: the motors idle, their summed thrust (a negative desired force counts as 0: the motor is off)
    at or below ``idle_N`` (N). A log of COMMANDED thrust (``motor_time_constant_s`` its motors' lag, s) reaches
    the air through the lag: a stretch of idle commands counts only where the thrust the motors deliver (the
    command through the lag, :func:`proxplan.identify.measure.motor_lag_compensated_N`) falls to the idle share
    within it, and then from the stretch's first sample (a cut to land is idle from the cut, as before)."""
    thrust_N = np.clip(log.motor_thrust_N, 0.0, None)
    idle = thrust_N.sum(axis=1) <= idle_N
    if not motor_time_constant_s or len(log) < 2 or not idle.any():
        return idle
    dt_s = float(np.median(np.diff(log.t_s)))
    delivered_N = motor_lag_compensated_N(thrust_N, dt_s, motor_time_constant_s).sum(axis=1)
    first = idle & ~np.concatenate([[False], idle[:-1]])  # first sample of each idle stretch
    run = np.maximum(np.cumsum(first) - 1, 0)  # the stretch each sample follows (read at idle samples only)
    lowest_N = np.minimum.reduceat(np.where(idle, delivered_N, np.inf), np.flatnonzero(first))  # per stretch
    return idle & (lowest_N[run] <= idle_N)


def check_log(
    log: VehicleLog,
    *,
    weight_N: float,
    ground_z_m: float = 0.0,
    options: QualityOptions = QualityOptions(),
    motor_time_constant_s: float | None = None,
) -> tuple[VehicleLog, Exclusions]:
    """Clean one log: drop NaN rows, split at gaps, drop short segments and ground contact.

    Args:
        log: as read by :func:`read_log`.
        weight_N: the vehicle's weight (idle-motor check), N.
        ground_z_m: ground height in the log's world frame, m.
        motor_time_constant_s: where the log's motor thrust is COMMANDED, the motors' first-order lag that
            the measurement compensates (:func:`proxplan.identify.loading.measure_options_for`), s; the idle
            test then asks the thrust the motors deliver to reach the idle share too (:func:`_idle_motors`): a
            command dipping below it for much less than the lag is no idle motor (stop 64: one such 10 ms dip in
            flight, 0.74 m up, split a generated log there and restarted the lag at a wild command, 19 mN RMS).
            None: the logged thrust is delivered.
    Returns:
        The cleaned log (``segment`` numbers contiguous stretches) and the exclusion counts.
    Raises:
        UserError: time going backwards or repeating (names the file and the row).
    """
    t = log.t_s
    dt = np.diff(t)
    finite_t = np.isfinite(t)
    bad = np.flatnonzero(np.isfinite(dt) & (dt <= 0.0))
    if bad.size:
        i = int(bad[0]) + 1
        raise UserError(
            f"{log.source}: time goes backwards or repeats at data row {i + 1} "
            f"({t[i - 1]:.6f} s -> {t[i]:.6f} s); logs must have increasing time"
        )
    table = log.as_table()
    if log.motor_pwm is not None and log.vbat_V is not None:
        table = np.column_stack([table, log.motor_pwm, log.vbat_V])
    finite = finite_t & np.all(np.isfinite(table), axis=1)
    nan_rows = int((~finite).sum())
    log = log.take(finite)
    if len(log) < 2:
        raise UserError(f"{log.source}: fewer than 2 usable rows (NaN rows: {nan_rows})")
    # ground contact / idle motors (before segmenting, so they split segments too); a motor asked for a
    # negative force is off (its floor), so the idle test sums the desired forces clipped at zero
    on_ground = log.position_m[:, 2] - ground_z_m <= options.ground_clearance_m
    idle = _idle_motors(log, options.min_thrust_fraction * weight_N, motor_time_constant_s)
    airborne = ~on_ground & ~idle
    ground = int((~airborne).sum())
    guard, n_impacts = impact_guard(log.t_s, log.velocity_mps[:, 2], on_ground, options)
    guard &= airborne
    airborne &= ~guard
    # segments: a new one starts after every gap and every excluded stretch
    step = np.diff(log.t_s)
    breaks = np.concatenate([[True], (step > options.max_gap_s)])
    gaps = int((step > options.max_gap_s).sum())
    breaks |= np.concatenate([[True], airborne[1:] & ~airborne[:-1]])
    seg = np.cumsum(breaks) - 1
    log = replace(log, segment=seg).take(airborne)
    short = 0
    if len(log):
        ids, counts = np.unique(log.segment, return_counts=True)
        keep = np.ones(len(log), dtype=bool)
        for sid, n in zip(ids, counts):
            m = log.segment == sid
            if log.t_s[m][-1] - log.t_s[m][0] < options.min_segment_s:
                keep &= ~m
                short += int(n)
        log = log.take(keep)
        _, seg = np.unique(log.segment, return_inverse=True)
        log = replace(log, segment=seg)
    return log, Exclusions(nan_rows=nan_rows, gap_segments=gaps, short_segment_samples=short, ground_samples=ground,
                           impact_samples=int(guard.sum()), impacts=n_impacts)  # fmt: skip
