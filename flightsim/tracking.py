"""Trackable kinematic limits and the tracking tube of a vehicle type, measured with the default
simulated controller (the Crazyflie firmware's Mellinger law, :mod:`proxplan.flightsim.mellinger`).

Procedure (:func:`measure_tracking`, ``proxplan track-limits``): the vehicle flies alone (no
downwash, no sensor noise, RotorPy's rotor drag on) the drag-compensated reference the export uploads
(:mod:`proxplan.planfile.reference`; the error is measured against the plan) along :data:`COURSE_M`, rest-to-rest straight
segments (horizontal 2.1 m, vertical 0.6 m, diagonal, short 0.2 m hops) timed by Ruckig at each
level of a ladder of limits: speed :data:`SPEED_LADDER_MPS` x acceleration :data:`ACCEL_LADDER_MPS2`
x jerk = :data:`JERK_PER_ACCEL_PS` x acceleration. A level is physically allowed when its
acceleration keeps the thrust within (1 - :data:`ATTITUDE_HEADROOM`) of the maximum when pointing
straight up (m (g + a) <= 0.8 T_max) and the tilt within :data:`MAX_TILT_DEG` (a <= g tan 35 deg).
It is accepted when, flown, the :data:`ERROR_QUANTILE` quantile of the position error plus the
margin :data:`TUBE_MARGIN_M` stays within the tube budget, and the motors saturate for at most
:data:`MAX_SATURATED_FRACTION` of the flight. Of the accepted levels the one flying the course
fastest is kept: its limits go to ``Vehicle.kinematics``, its error quantile + margin is the type's
tracking tube, ``Vehicle.tracking`` records the measurement.

What limits it (docs/flying.md): with the drag compensated, the attitude and motor dynamics the
firmware's feed-forward does not cover and the 100 Hz set-point hold (~1-1.5 cm at 2 m/s, 4 m/s^2);
without it, RotorPy's rotor drag (~0.24 m/s^2 per m/s) against the firmware's soft position gain
(0.4 N/m on 32 g) left a cruise lag of ~1.9 cm per m/s.
"""

from __future__ import annotations

import dataclasses
import datetime
import math
from dataclasses import dataclass

import numpy as np

from proxplan.flightsim.options import SimulationOptions
from proxplan.flightsim.simulate import simulate_plan
from proxplan.physics import (
    GRAVITY_MPS2,
    TRACKING_COURSE,
    TUBE_BUDGET_M,
    TUBE_MARGIN_M,
    KinematicLimits,
    TrackingMeasurement,
    Vehicle,
)
from proxplan.planfile import Plan, VehicleTrajectory

COURSE_M = np.array(
    [[0.0, 0.0, 1.0], [2.0, 0.6, 1.0], [2.0, 0.6, 1.6], [0.5, 0.0, 1.2], [0.5, 0.0, 1.0], [0.0, 0.0, 1.0]]
)
"""Waypoints of the calibration course, world frame, m (rest at each)."""
SPEED_LADDER_MPS = (0.75, 1.0, 1.25, 1.5, 1.75, 2.0)
ACCEL_LADDER_MPS2 = (1.0, 1.5, 2.0, 2.5, 3.0, 4.0)
JERK_PER_ACCEL_PS = (4.0, 10.0)
"""Jerk limits of the ladder as multiples of its acceleration, 1/s."""
ERROR_QUANTILE = 0.99
ATTITUDE_HEADROOM = 0.2  # share of the maximum thrust kept for attitude control, -
MAX_TILT_DEG = 35.0  # largest tilt a level may ask for, deg
MAX_SATURATED_FRACTION = 0.02  # motor-saturated share of the flight accepted, -


@dataclass(frozen=True)
class CourseFlight:
    """One flight of the course at ``limits``: errors m, saturated time s, course duration s."""

    limits: KinematicLimits
    quantile_error_m: float
    max_error_m: float
    saturation_s: float
    duration_s: float
    allowed: bool  # within thrust-to-weight and tilt
    accepted: bool
    reason: str  # why not accepted ("" when accepted)


@dataclass(frozen=True)
class TrackingResult:
    """A measurement: the vehicle with its measured limits and tube, and every flight of the ladder."""

    vehicle: Vehicle
    flights: tuple[CourseFlight, ...]

    def to_dict(self) -> dict:
        assert self.vehicle.tracking is not None and self.vehicle.kinematics is not None
        return {
            "vehicle": self.vehicle.name,
            "kinematic_limits": dataclasses.asdict(self.vehicle.kinematics),
            "tracking_tube_m": self.vehicle.tracking.tube_m,
            "tracking": dataclasses.asdict(self.vehicle.tracking),
            "flights": [
                {**dataclasses.asdict(f), "limits": dataclasses.asdict(f.limits)} for f in self.flights if f.allowed
            ],
        }


def course_plan(vehicle: Vehicle, limits: KinematicLimits, *, dt_s: float = 0.05) -> Plan:
    """A one-vehicle plan along :data:`COURSE_M`, timed with Ruckig at ``limits``."""
    from proxplan.planner import common_grid, time_parameterize

    timed = time_parameterize(COURSE_M, None, limits)
    t = common_grid(timed.duration_s, dt_s)
    p, v, a = timed.sample(t)
    return Plan("tracking-course", dt_s, {"v": VehicleTrajectory("v", vehicle.name, vehicle, t, p, v, a)})


def thrust_accel_limit_mps2(vehicle: Vehicle) -> float:
    """Largest acceleration norm a level may use, m/s^2: m (g + a) <= (1 - headroom) T_max and
    a <= g tan(MAX_TILT_DEG)."""
    climb = ((1.0 - ATTITUDE_HEADROOM) * vehicle.max_thrust_N / vehicle.mass_kg) - GRAVITY_MPS2
    return float(max(0.0, min(climb, GRAVITY_MPS2 * math.tan(math.radians(MAX_TILT_DEG)))))


def fly_course(
    vehicle: Vehicle,
    limits: KinematicLimits,
    *,
    controller: str = "mellinger",
    quantile: float = ERROR_QUANTILE,
    drag_compensation: bool = True,
) -> tuple[float, float, float, float]:
    """Fly the course at ``limits``: (error quantile m, max error m, saturated time s, duration s)."""
    plan = course_plan(vehicle, limits)
    options = SimulationOptions(
        imu_noise=False, settle_s=0.5, controller=controller, drag_compensation=drag_compensation
    )
    res = simulate_plan(plan, options=options)
    rec = res.records["v"]
    err = np.linalg.norm(rec.position_m - rec.ref_position_m, axis=1)
    return float(np.quantile(err, quantile)), float(err.max()), float(res.saturation_time_s["v"]), plan.makespan_s


def course_tracking_error_m(
    vehicle: Vehicle, limits: KinematicLimits | None = None, *, drag_compensation: bool = True
) -> float:
    """Largest position error, m, of ``vehicle`` flown alone by the default controller along the
    calibration course at ``limits`` (default: the vehicle's own)."""
    return fly_course(vehicle, limits or vehicle.kinematic_limits, drag_compensation=drag_compensation)[1]


def ladder() -> list[KinematicLimits]:
    """Every level of the measurement ladder (speed m/s, acceleration m/s^2, jerk m/s^3)."""
    return [
        KinematicLimits(v, a, a * j) for v in SPEED_LADDER_MPS for a in ACCEL_LADDER_MPS2 for j in JERK_PER_ACCEL_PS
    ]


def measure_tracking(
    vehicle: Vehicle,
    *,
    budget_m: float = TUBE_BUDGET_M,
    margin_m: float = TUBE_MARGIN_M,
    quantile: float = ERROR_QUANTILE,
    controller: str = "mellinger",
    levels: list[KinematicLimits] | None = None,
    command: str = "",
    progress: bool = False,
    drag_compensation: bool = True,
) -> TrackingResult:
    """Measure ``vehicle``'s trackable limits and tube (module docstring); ``levels`` replaces the
    ladder (tests). Raises ValueError when no level is accepted."""
    cap = thrust_accel_limit_mps2(vehicle)
    levels = levels if levels is not None else ladder()
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(levels), desc=f"track-limits {vehicle.name}", unit="flight", leave=False)
    flights = []
    for lim in levels:
        if lim.max_accel_mps2 > cap + 1e-9:
            reason = f"acceleration {lim.max_accel_mps2:g} m/s^2 > {cap:.2f} m/s^2 (thrust-to-weight / tilt)"
            flights.append(CourseFlight(lim, math.nan, math.nan, math.nan, math.nan, False, False, reason))
        else:
            q, mx, sat, dur = fly_course(
                vehicle, lim, controller=controller, quantile=quantile, drag_compensation=drag_compensation
            )
            reason = ""
            if q + margin_m > budget_m:
                reason = (
                    f"error quantile {q * 100:.1f} cm + margin {margin_m * 100:.1f} cm > budget {budget_m * 100:.1f} cm"
                )
            elif sat > MAX_SATURATED_FRACTION * dur:
                reason = f"motors saturated {sat:.3f} s of {dur:.2f} s"
            flights.append(CourseFlight(lim, q, mx, sat, dur, True, not reason, reason))
        if bar is not None:
            bar.update(1)
    if bar is not None:
        bar.close()
    accepted = [f for f in flights if f.accepted]
    if not accepted:
        raise ValueError(f"{vehicle.name}: no level of the ladder is tracked within {budget_m * 100:.1f} cm")
    best = min(accepted, key=lambda f: (round(f.duration_s, 6), f.quantile_error_m))
    faster = [f for f in flights if f.allowed and not f.accepted and f.duration_s < best.duration_s]
    if faster:
        nxt = max(faster, key=lambda f: f.duration_s)  # the closest faster level
        lm = nxt.limits
        limited_by = (
            f"next faster level ({lm.max_speed_mps:g} m/s, {lm.max_accel_mps2:g} m/s^2, "
            f"{lm.max_jerk_mps3:g} m/s^3): {nxt.reason}"
        )
    else:
        limited_by = "the ladder's fastest level"
    measurement = TrackingMeasurement(
        controller=controller,
        tube_m=round(best.quantile_error_m + margin_m, 4),
        error_quantile=quantile,
        quantile_error_m=best.quantile_error_m,
        max_error_m=best.max_error_m,
        margin_m=margin_m,
        budget_m=budget_m,
        saturation_s=best.saturation_s,
        limited_by=limited_by,
        course=TRACKING_COURSE,
        command=command
        or f"proxplan track-limits --vehicle {vehicle.name} --budget {budget_m:g}"
        + ("" if drag_compensation else " --no-drag-compensation"),
        date=datetime.date.today().isoformat(),
    )
    measured = dataclasses.replace(vehicle, kinematics=best.limits, tracking=measurement)
    return TrackingResult(measured, tuple(flights))
