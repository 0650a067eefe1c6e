"""Moves on a time grid: straight rest-to-rest moves (one jerk-limited 1-D profile, scaled along a
line, :class:`LineMove`) and flights through waypoints without stopping (:class:`RunMove`).

:func:`rest_to_rest` gives the time-optimal Ruckig profile (1 DOF, norm limits) over a distance,
stretched in time to a whole number of grid steps ``dt_s`` (stretching by c <= 1 scales velocity,
acceleration and jerk by c, c^2, c^3, so the limits still hold); so every move starts and ends on the
grid and a trajectory sampled on the grid is exactly the trajectory that is flown.
:class:`LineMove` flies a straight segment p0 -> p1 along a profile whose distance is at least
|p1 - p0|: the position is p0 + (sigma(t) / D) (p1 - p0). Vehicles of one synchronous step share one
profile (the step's longest move, at the group's common limits), so their relative positions move
on straight lines (:mod:`proxplan.planner.swarm.sync`). ``LineMove`` offers ``duration`` and
``at_time`` like a ``ruckig.Trajectory``, so it is a segment of :class:`~proxplan.planner.timing.paths.TimedPath`.

:class:`RunMove` flies from rest at its first waypoint through the others, at the speeds
:func:`~proxplan.planner.timing.corners.corner_speeds` chooses locally, to rest at its last
(:func:`~proxplan.planner.timing.corners.through_run`: state-to-state Ruckig segments, never Ruckig's
intermediate-waypoint feature), stretched in time so that it lasts a whole number of grid steps.
Both offer ``steps``, ``end_m``, ``positions()`` (the grid samples) and ``at_time``.
"""

from __future__ import annotations

import math
from bisect import bisect_right
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from proxplan.physics import KinematicLimits


@dataclass(frozen=True)
class Profile:
    """Rest-to-rest motion over ``distance_m`` (m) in ``steps`` grid steps of ``dt_s`` (s)."""

    distance_m: float
    dt_s: float
    steps: int
    stretch: float  # time-stretch factor c (Ruckig's time = c x grid time), <= 1
    arc_m: np.ndarray  # (steps + 1,) distance covered at k dt_s, m
    limits: KinematicLimits
    _traj: object  # ruckig.Trajectory (1 DOF)

    def __reduce__(self):  # a Ruckig trajectory does not pickle: rebuild it (Dask tasks return moves)
        return rest_to_rest, (self.distance_m, self.limits, self.dt_s)

    @property
    def duration_s(self) -> float:
        return self.steps * self.dt_s

    def at(self, t_s: float) -> tuple[float, float, float]:
        """Distance m, speed m/s and acceleration m/s^2 along the move at time ``t_s``."""
        if t_s <= 0.0:
            return 0.0, 0.0, 0.0
        if t_s >= self.duration_s:
            return self.distance_m, 0.0, 0.0
        c = self.stretch
        p, v, a = self._traj.at_time(c * t_s)  # type: ignore[attr-defined]
        return float(p[0]), c * float(v[0]), c * c * float(a[0])


# Ruckig 0.x raises on a distance a rounding error off a boundary between its profile types (at
# 2 m/s, 4 m/s^2, 16 m/s^3: 0.4999999999999999 m, where the acceleration just reaches its limit,
# 2 a^3 / j^2 = 0.5 m); such a distance is planned once more, longer by this fraction (a nanometre
# per metre: the move ends within it of its end, and the profile stays within the limits)
RUCKIG_RETRY_NUDGE = 1e-9


@lru_cache(maxsize=4096)
def rest_to_rest(distance_m: float, limits: KinematicLimits, dt_s: float) -> Profile:
    """The time-optimal rest-to-rest :class:`Profile` over ``distance_m`` (m), on the ``dt_s`` grid."""
    from ruckig import InputParameter, Result, Ruckig, RuckigError, Trajectory

    if distance_m <= 0.0:
        return Profile(0.0, dt_s, 0, 1.0, np.zeros(1), limits, None)
    inp = InputParameter(1)
    inp.current_velocity, inp.target_velocity = [0.0], [0.0]
    inp.max_velocity = [limits.max_speed_mps]
    inp.max_acceleration = [limits.max_accel_mps2]
    inp.max_jerk = [limits.max_jerk_mps3]
    traj = Trajectory(1)
    for target in (float(distance_m), float(distance_m) * (1.0 + RUCKIG_RETRY_NUDGE)):
        inp.current_position, inp.target_position = [0.0], [target]
        try:
            result = Ruckig(1).calculate(inp, traj)
            break
        except RuckigError:  # a distance on a boundary between profile types, by rounding: nudged once
            if target != float(distance_m):
                raise
    if result not in (Result.Working, Result.Finished):
        raise RuntimeError(f"Ruckig failed on a rest-to-rest profile ({result})")
    duration = float(traj.duration)
    steps = max(1, int(math.ceil(duration / dt_s - 1e-9)))
    stretch = duration / (steps * dt_s)
    arc = np.array([traj.at_time(min(stretch * k * dt_s, duration))[0][0] for k in range(steps + 1)])
    arc[-1] = distance_m
    return Profile(float(distance_m), dt_s, steps, stretch, arc, limits, traj)


class LineMove:
    """A straight move p0 -> p1 (m) along ``profile`` (whose distance is >= |p1 - p0|), see module."""

    def __init__(self, p0_m: np.ndarray, p1_m: np.ndarray, profile: Profile):
        self.p0 = np.asarray(p0_m, dtype=float)
        self.delta = np.asarray(p1_m, dtype=float) - self.p0
        self.profile = profile
        self.scale = 0.0 if profile.distance_m <= 0.0 else 1.0 / profile.distance_m
        self.duration = profile.duration_s
        self.steps = profile.steps
        self.end_m = self.p0 + self.delta * (profile.arc_m[-1] * self.scale)

    def at_time(self, t_s: float) -> tuple[list[float], list[float], list[float]]:
        s, v, a = self.profile.at(t_s)
        k = self.scale
        return (
            (self.p0 + s * k * self.delta).tolist(),
            (v * k * self.delta).tolist(),
            (a * k * self.delta).tolist(),
        )

    def positions(self) -> np.ndarray:
        """Positions at every grid time 0, dt, ..., duration (steps + 1, 3), m."""
        return self.p0[None] + (self.profile.arc_m * self.scale)[:, None] * self.delta[None]


class RunMove:
    """A flight from rest at ``waypoints_m[0]`` through the interior waypoints to rest at the last
    (K >= 2, 3), m, on the ``dt_s`` grid (see module); ``deviation_m`` bounds the corner cut."""

    def __init__(self, waypoints_m: np.ndarray, limits: KinematicLimits, dt_s: float, *, deviation_m: float):
        from proxplan.planner.timing.corners import through_run

        self.waypoints_m = np.asarray(waypoints_m, dtype=float).reshape(-1, 3)
        self._args = (limits, dt_s, deviation_m)
        self.pieces = through_run(self.waypoints_m, limits, deviation_m=deviation_m)
        self.knots_s = [0.0]  # Ruckig time at the start of each piece, s
        for tr in self.pieces:
            self.knots_s.append(self.knots_s[-1] + float(tr.duration))
        total = self.knots_s[-1]
        self.steps = max(1, int(math.ceil(total / dt_s - 1e-9)))
        self.dt_s = dt_s
        self.stretch = total / (self.steps * dt_s)  # Ruckig time = stretch x grid time, <= 1
        self.duration = self.steps * dt_s
        self.end_m = self.waypoints_m[-1].copy()

    def __reduce__(self):  # Ruckig trajectories do not pickle: rebuild them (the same, deterministically)
        limits, dt_s, deviation_m = self._args
        return _run_move, (self.waypoints_m, limits, dt_s, deviation_m)

    def at_time(self, t_s: float) -> tuple[list[float], list[float], list[float]]:
        """Position m, velocity m/s, acceleration m/s^2 at ``t_s`` after the start (rest outside)."""
        if t_s <= 0.0:
            return self.waypoints_m[0].tolist(), [0.0] * 3, [0.0] * 3
        if t_s >= self.duration:
            return self.end_m.tolist(), [0.0] * 3, [0.0] * 3
        c = self.stretch
        tau = c * t_s
        k = min(bisect_right(self.knots_s, tau) - 1, len(self.pieces) - 1)
        p, v, a = self.pieces[k].at_time(min(tau - self.knots_s[k], float(self.pieces[k].duration)))
        return list(p), [c * x for x in v], [c * c * x for x in a]

    def positions(self, per_step: int = 1) -> np.ndarray:
        """Positions every ``dt_s / per_step`` from 0 to the end (steps x per_step + 1, 3), m."""
        n = self.steps * per_step
        h = self.stretch * self.dt_s / per_step
        out: list = []
        k = 0
        for i, tr in enumerate(self.pieces):
            t0, t1 = self.knots_s[i], self.knots_s[i + 1]
            while k <= n and (k * h < t1 or i == len(self.pieces) - 1):
                out.append(tr.at_time(min(max(k * h - t0, 0.0), t1 - t0))[0])
                k += 1
        arr = np.array(out[: n + 1], dtype=float)
        arr[0], arr[-1] = self.waypoints_m[0], self.end_m
        return arr


def _run_move(waypoints_m: np.ndarray, limits: KinematicLimits, dt_s: float, deviation_m: float) -> RunMove:
    return RunMove(waypoints_m, limits, dt_s, deviation_m=deviation_m)
