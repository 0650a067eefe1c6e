"""Jerk-limited time parameterisation of waypoint paths with Ruckig (community edition).

Each path is a chain of state-to-state Ruckig segments between consecutive waypoints (world frame,
m), never Ruckig's intermediate-waypoint feature (that one calls a cloud API). Segments end at rest
(target velocity 0) and use phase synchronisation, so every segment is a straight line in space;
per-axis limits are the vehicle's limits scaled by the segment's direction cosines, so the norms of
velocity (m/s), acceleration (m/s^2) and jerk (m/s^3) stay within the vehicle's limits. A segment's
``minimum_duration`` is the time the space-time planner scheduled for it, so the timed trajectory
reaches every waypoint exactly when the planner said (waits are plain holds).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from proxplan.physics import KinematicLimits
from proxplan.planner.timing.corners import through_run
from proxplan.planner.timing.segments import ruckig_segment


@dataclass
class TimedPath:
    """A chain of Ruckig segments; ``knot_t_s`` (K,) are the waypoint times, s."""

    knot_t_s: np.ndarray
    knot_p_m: np.ndarray  # (K, 3)
    segments: list  # ruckig.Trajectory or None (hold) per segment

    @property
    def duration_s(self) -> float:
        return float(self.knot_t_s[-1])

    def sample(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position m, velocity m/s, acceleration m/s^2 at times ``t_s`` (M,), each (M, 3).

        Before the first knot and after the last the vehicle holds its first/last waypoint."""
        t_s = np.asarray(t_s, dtype=float)
        p = np.empty((t_s.size, 3))
        v = np.zeros((t_s.size, 3))
        a = np.zeros((t_s.size, 3))
        seg = (
            np.clip(np.searchsorted(self.knot_t_s, t_s, side="right") - 1, 0, len(self.segments) - 1)
            if self.segments
            else None
        )
        for i, t in enumerate(t_s):
            if not self.segments or t <= self.knot_t_s[0]:
                p[i] = self.knot_p_m[0]
                continue
            if t >= self.knot_t_s[-1]:
                p[i] = self.knot_p_m[-1]
                continue
            assert seg is not None
            k = int(seg[i])
            traj = self.segments[k]
            if traj is None:
                p[i] = self.knot_p_m[k]
                continue
            pos, vel, acc = traj.at_time(float(t - self.knot_t_s[k]))
            p[i], v[i], a[i] = pos, vel, acc
        return p, v, a


def time_parameterize(
    waypoints_m: np.ndarray,
    times_s: np.ndarray | None,
    limits: KinematicLimits,
) -> TimedPath:
    """Ruckig-time a waypoint path.

    Args:
        waypoints_m: (K, 3) waypoints, world frame, m (K >= 1).
        times_s: (K,) scheduled arrival times, s, non-decreasing, or None for time-optimal
            segments starting at t = 0. A segment is never shorter than the schedule; if the
            schedule is shorter than the jerk-limited minimum, the later knots are pushed back.
        limits: norm limits of the vehicle.

    Returns:
        A :class:`TimedPath` whose knot times are the actual (possibly pushed back) arrival times.
    """
    pts = np.asarray(waypoints_m, dtype=float).reshape(-1, 3)
    sched = None if times_s is None else np.asarray(times_s, dtype=float)
    t0 = 0.0 if sched is None else float(sched[0])
    knots = [t0]
    segments: list = []
    for k in range(len(pts) - 1):
        d = pts[k + 1] - pts[k]
        dist = float(np.linalg.norm(d))
        want = 0.0 if sched is None else float(sched[k + 1]) - knots[-1]  # time left to the schedule
        if dist < 1e-9:
            segments.append(None)
            knots.append(knots[-1] + max(want, 0.0))
            continue
        traj = ruckig_segment(pts[k], pts[k + 1], limits, minimum_duration_s=want if want > 0.0 else None)
        segments.append(traj)
        dur = float(traj.duration)
        knots.append(knots[-1] + dur)
    return TimedPath(np.array(knots), pts.copy(), segments)


def time_parameterize_through(waypoints_m: np.ndarray, times_s: np.ndarray, limits: KinematicLimits) -> TimedPath:
    """Like :func:`time_parameterize`, but each moving run (consecutive distinct waypoints) passes
    its interior waypoints without stopping (:func:`through_run`), at minimum
    time; waits (repeated waypoints) end at their scheduled times. State-to-state Ruckig segments
    with target velocities, never Ruckig's intermediate-waypoint feature. Segments are not straight
    lines near the waypoints: the caller re-checks the timed trajectory."""
    pts = np.asarray(waypoints_m, dtype=float).reshape(-1, 3)
    sched = np.asarray(times_s, dtype=float)
    knots = [float(sched[0])]
    segments: list = []
    k = 0
    n = len(pts)
    while k < n - 1:
        if float(np.linalg.norm(pts[k + 1] - pts[k])) < 1e-9:
            segments.append(None)
            knots.append(max(knots[-1], float(sched[k + 1])))
            k += 1
            continue
        j = k + 1
        while j < n - 1 and float(np.linalg.norm(pts[j + 1] - pts[j])) > 1e-9:
            j += 1
        for traj in through_run(pts[k : j + 1], limits):
            segments.append(traj)
            knots.append(knots[-1] + float(traj.duration))
        k = j
    return TimedPath(np.array(knots), pts.copy(), segments)


def common_grid(end_s: float, dt_s: float) -> np.ndarray:
    """The common time grid 0, dt, ..., >= end_s (M,), s."""
    n = int(math.ceil(end_s / dt_s - 1e-9)) + 1
    return np.arange(n) * dt_s
