"""How closely the default controller tracks a vehicle's kinematic limits: the measurement behind
the limits on :class:`proxplan.physics.Vehicle` and the tube margin ``limits.tracking_margin_m``.

Why plans were flown with 12-24 cm errors (docs/flying.md): RotorPy's SE(3) controller has no
angular-rate feed-forward from the reference jerk, and its attitude loop (k_R = 310 s^-2,
k_w = 57 s^-1, the Crazyflie gains) has a slow pole at s = -6.1 s^-1, so the realised acceleration
lags the reference by ~0.15 s. Every acceleration phase therefore leaves a velocity deficit of about
a x 0.15 s, and the position error grows with the velocity change of a segment: ~13 cm for
rest-to-rest segments at 1.5 m/s, 3 m/s^2, 15 m/s^3 (the earlier built-in limits), 4.4 cm at
1 m/s, 1 m/s^2, 2 m/s^3. The position and attitude gains are normalised by mass and inertia, so
the error is the same for every built-in type; motor lag (0.04-0.072 s) and rotor drag change it
by < 1 cm.

:func:`course_tracking_error_m` flies one vehicle alone (no downwash, no noise) along a fixed
course of rest-to-rest, Ruckig-timed straight segments (horizontal, vertical and diagonal) at the
given limits and returns its largest position error; :func:`trackable_scale` finds the largest
scaling of a set of limits that keeps it under a budget.
"""

from __future__ import annotations

import numpy as np

from proxplan.flightsim.simulate import SimulationOptions, simulate_plan
from proxplan.physics import KinematicLimits, Vehicle
from proxplan.planfile import Plan, VehicleTrajectory

COURSE_M = np.array(
    [[0.0, 0.0, 1.0], [2.0, 0.6, 1.0], [2.0, 0.6, 1.6], [0.5, 0.0, 1.2], [0.5, 0.0, 1.0], [0.0, 0.0, 1.0]]
)
"""Waypoints of the calibration course, world frame, m (rest at each)."""


def course_plan(vehicle: Vehicle, limits: KinematicLimits, *, dt_s: float = 0.05) -> Plan:
    """A one-vehicle plan along :data:`COURSE_M`, timed with Ruckig at ``limits``."""
    from proxplan.planner import common_grid, time_parameterize

    timed = time_parameterize(COURSE_M, None, limits)
    t = common_grid(timed.duration_s, dt_s)
    p, v, a = timed.sample(t)
    return Plan("tracking-course", dt_s, {"v": VehicleTrajectory("v", vehicle.name, vehicle, t, p, v, a)})


def course_tracking_error_m(vehicle: Vehicle, limits: KinematicLimits | None = None) -> float:
    """Largest position error, m, of ``vehicle`` flown alone by the default controller along the
    calibration course at ``limits`` (default: the vehicle's own)."""
    plan = course_plan(vehicle, limits or vehicle.kinematic_limits)
    rec = simulate_plan(plan, options=SimulationOptions(imu_noise=False, settle_s=0.5)).records["v"]
    return float(np.linalg.norm(rec.position_m - rec.ref_position_m, axis=1).max())


def trackable_scale(vehicle: Vehicle, limits: KinematicLimits, budget_m: float, *, iterations: int = 8) -> float:
    """Largest factor s in (0, 1] (bisection) such that the limits (s v, s a, s j) keep the course
    tracking error within ``budget_m``, m."""
    lo, hi = 0.0, 1.0
    if course_tracking_error_m(vehicle, limits) <= budget_m:
        return 1.0
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        scaled = KinematicLimits(limits.max_speed_mps * mid, limits.max_accel_mps2 * mid, limits.max_jerk_mps3 * mid)
        if course_tracking_error_m(vehicle, scaled) <= budget_m:
            lo = mid
        else:
            hi = mid
    return lo
