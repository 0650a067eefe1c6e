"""Motor thrust from PWM and battery voltage where a log holds no force (uSD, ROS 2, PX4 logs).

Stock firmware logs the PWM it sends each motor and the battery voltage, never a force. The force a
brushed motor delivers follows its mean voltage x = pwm * Vbat (V): the same per-motor map as
:class:`proxplan.identify.thrust_map.ThrustMap` (D(x) = P(clip(x, 0, x_max)) within 0..P(x_max)), so the
measurement, the motor limits, the motor lag and the self-check downstream are the ones of logged
forces. Where the map comes from is reported per vehicle (``thrust_source``):

* ``pwm_published_map`` — a published map for the type (:data:`PUBLISHED_MAPS`): the Crazyflie 2.x
  map of Foerster (2015, eq. 3.3), f [N] = c0 + c1 p + c2 p^2 of the raw PWM p (0..65536), measured
  at a battery of :data:`FOERSTER_REFERENCE_V`; at another battery voltage the motor gets the mean
  voltage x, so p = 65536 x / V_ref (a quadratic in x).
* ``pwm_free_flight_scale`` — no published map for the type (the Parrot-frame vehicles, any custom
  type): the shape of the log's base map (:data:`SHAPES`) times one scale per vehicle type, fitted on
  the TRAIN flights' free flight (:func:`calibrate_scale`): where no vehicle is overhead, out of ground
  effect and every motor in range, the aerodynamic force is small, so the scale s minimises the measured
  vertical force there: F_z(s) = m (R alpha)_z - s T_z (S0-11), linear in s.
* ``pwm_published_map_free_flight_scale`` — a published map's scale checked the same way: the map keeps
  its shape (its voltage dependence) and takes the free-flight scale, which the map records (``scale``:
  how far the published map was off for these vehicles). On the Neural-Swarm crazyflie-2.1 logs the
  published map as published over-predicts the thrust (scale < 1; docs/identify.md), and the scale is
  what makes the published map usable there. Without free-flight train samples (evaluate on a saved
  model: the model's map is used) the published map is used as published (``pwm_published_map``).

Motor limits without a logged force (:func:`pwm_limits`): a motor is at its FLOOR where its PWM is 0
(at most :data:`proxplan.identify.thrust_map.PWM_FLOOR`), at its CEILING where its PWM is full scale
(65535 of 65536 counts: the firmware clamps there). A firmware that caps the motor voltage below full
scale (the Neural-Swarm firmware: pwm * Vbat <= ~3.3 V) is not flagged at that cap; the delivered force
is right either way (it is the PWM's force), only the ``at_limit`` strata and the self-check's
"every motor in range" then miss those samples.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from proxplan.fileio import UserError
from proxplan.identify.thrust_map import CEILING, FLOOR, PWM_FLOOR, ThrustMap

if TYPE_CHECKING:
    from proxplan.identify.measure import MeasureOptions
    from proxplan.identify.vehicle_log import VehicleLog
    from proxplan.physics import Vehicle

PWM_FULL_SCALE = 65536
"""Raw PWM counts per unit of the normalised PWM (the Neural-Swarm logs' normalisation, pwm / 65536)."""
FOERSTER_COEF = (5.484560e-4, 1.032633e-6, 2.130295e-11)
"""Foerster (2015), System identification of the Crazyflie 2.0 nano quadrocopter, eq. 3.3: per-motor
thrust f [N] = c0 + c1 p + c2 p^2 of the raw PWM p (0..65536); the coefficients N, N/count, N/count^2
(the values the shared Neural-Swarm README quotes)."""
FOERSTER_REFERENCE_V = 3.57
"""Battery voltage at which the Foerster map holds, V. Derived from Bitcraze's published thrust table
of the Crazyflie 2.0 (PWM 6.25-62.5 %, battery 3.98-3.65 V, whole-vehicle thrust 1.6-32.8 g; "PWM to
thrust", Bitcraze firmware documentation): least squares of 4 f(65536 pwm V / V_ref) against the
measured thrust gives V_ref = 3.57 V (0.36 g RMS over the 10 rows; with the PWM alone, no voltage,
1.2 g RMS). Never fitted on the project's logs."""
MAX_MOTOR_VOLTAGE_V = 4.2
"""Top of a published map's range: a full 1S LiPo, the most a motor can get, V."""
PUBLISHED_MAPS = {"crazyflie-2.1": "foerster2015"}
"""Vehicle types with a published PWM*Vbat thrust map (key into :data:`SHAPES`)."""
SHAPES = ("foerster2015", "px4-thrust-model")
"""Base maps a log's PWM follows: ``foerster2015`` (Crazyflie PWM and battery voltage) or
``px4-thrust-model`` (PX4's normalised motor command c, relative thrust THR_MDL_FAC c^2 + (1 -
THR_MDL_FAC) c, PX4 doc of THR_MDL_FAC; the log's own parameter, 0 when absent)."""
SOURCE_PUBLISHED, SOURCE_PUBLISHED_SCALED, SOURCE_FREE_FLIGHT = (
    "pwm_published_map", "pwm_published_map_free_flight_scale", "pwm_free_flight_scale")  # fmt: skip
"""``thrust_source`` of a vehicle whose log holds no force (``logged_u``/``pwm`` are the logged-force ones):
the published map as published (no free-flight train samples to check its scale on), the published map
times its free-flight scale, or the base shape times its free-flight scale (no published map)."""
MIN_FREE_SAMPLES = 200
"""Fewer free-flight train samples of a type than this: its scale cannot be calibrated (UserError)."""


def foerster_map(scale: float = 1.0) -> ThrustMap:
    """The Crazyflie 2.x map of Foerster (2015) in x = pwm * Vbat (V), times ``scale`` (-)."""
    c0, c1, c2 = FOERSTER_COEF
    k = PWM_FULL_SCALE / FOERSTER_REFERENCE_V  # counts per volt of mean motor voltage
    coef = (scale * c0, scale * c1 * k, scale * c2 * k * k, 0.0)
    return ThrustMap(coef=coef, x_max_V=MAX_MOTOR_VOLTAGE_V, rms_N=0.0, n_fit=0, source="published:foerster2015")


def px4_map(thr_mdl_fac: float, scale: float = 1.0) -> ThrustMap:
    """PX4's thrust model of the normalised command c (x = c, the log's ``vbat`` set to 1): relative
    thrust fac c^2 + (1 - fac) c, times ``scale`` (N at c = 1)."""
    coef = (0.0, scale * (1.0 - thr_mdl_fac), scale * thr_mdl_fac, 0.0)
    return ThrustMap(coef=coef, x_max_V=1.0, rms_N=0.0, n_fit=0, source=f"px4-thrust-model:{thr_mdl_fac:g}")


def base_map(shape: str) -> ThrustMap:
    """The unscaled base map named by a log's ``thrust_shape`` (``foerster2015`` or
    ``px4-thrust-model:<THR_MDL_FAC>``)."""
    name, _, arg = shape.partition(":")
    if name == "foerster2015":
        return foerster_map()
    if name == "px4-thrust-model":
        return px4_map(float(arg or 0.0))
    raise ValueError(f"unknown thrust shape {shape!r}; expected one of {SHAPES}")


def pwm_limits(pwm: np.ndarray) -> np.ndarray:
    """(N, 4) int8 per motor of normalised PWM ``pwm`` (N, 4): FLOOR (PWM 0), CEILING (full scale) or 0."""
    out = np.zeros(pwm.shape, dtype=np.int8)
    out[pwm >= (PWM_FULL_SCALE - 1) / PWM_FULL_SCALE] = CEILING
    out[pwm <= PWM_FLOOR] = FLOOR
    return out


@dataclass(frozen=True)
class FreeFlight:
    """One train log for the scale fit: its vehicle, log (thrust at scale 1), measurement options and
    free-flight samples (N,) bool."""

    vehicle: Vehicle
    log: VehicleLog  # thrust at scale 1 of the base map
    options: MeasureOptions  # this vehicle's (motor lag)
    free: np.ndarray


def calibrate_scale(samples: Sequence[FreeFlight]) -> tuple[float, int]:
    """Scale s (-) of the base map minimising the free-flight vertical force, and the samples used.

    (S0-11) is linear in the thrust scale: F_z(s) = F_z(1) - (s - 1) h with h = F_z(1) - F_z(2) (the
    smoothed, lagged thrust's vertical part, from the project's own measurement at scales 1 and 2), so
    s = 1 + sum(F_z(1) h) / sum(h^2).
    """
    from proxplan.identify.measure import measure_log

    num = den = 0.0
    n = 0
    for s in samples:
        if not s.free.any():
            continue
        f1 = measure_log(s.vehicle, s.log, options=replace(s.options, thrust_scale=1.0)).force_N[s.free, 2]
        f2 = measure_log(s.vehicle, s.log, options=replace(s.options, thrust_scale=2.0)).force_N[s.free, 2]
        h = f1 - f2
        num += float(f1 @ h)
        den += float(h @ h)
        n += int(s.free.sum())
    if n < MIN_FREE_SAMPLES or den <= 0.0:
        raise UserError(
            f"thrust scale: {n} free-flight train samples (no vehicle overhead, above 0.3 m, motors in range); "
            f"need {MIN_FREE_SAMPLES} to calibrate a type without a published thrust map"
        )
    return 1.0 + num / den, n


def free_flight_mask(log: VehicleLog, ground_z_m: float, others: Sequence[tuple[float, VehicleLog]]) -> np.ndarray:
    """(N,) bool: samples of ``log`` in free flight: rotor plane above
    :data:`proxplan.identify.measure.FREE_HEIGHT_M`, no other vehicle above within r < 3 L of it
    (``others``: (its size L in m, its log), positions interpolated onto this clock), every motor in range
    within +-0.2 s (no PWM at its floor or full scale)."""
    from scipy.ndimage import maximum_filter1d

    from proxplan.identify.measure import FREE_HEIGHT_M
    from proxplan.identify.vehicle_log import interpolate_position_m

    free = log.position_m[:, 2] - ground_z_m > FREE_HEIGHT_M
    for size_m, other in others:
        off = log.position_m - interpolate_position_m(other, log.t_s)
        free &= ~((-off[:, 2] > 0.0) & (np.hypot(off[:, 0], off[:, 1]) < 3.0 * size_m))
    assert log.motor_pwm is not None  # a log without forces holds its PWM (identify.formats.contract)
    limit = np.any(pwm_limits(log.motor_pwm) != 0, axis=1).astype(np.uint8)
    dt = float(np.median(np.diff(log.t_s))) if len(log) > 1 else 0.01
    near = maximum_filter1d(limit, size=2 * max(1, int(round(0.2 / dt))) + 1, mode="nearest") > 0
    return free & ~near


def pwm_thrust_maps(
    shapes: Mapping[str, str], free_flight: Mapping[str, Sequence[FreeFlight]]
) -> tuple[dict[str, ThrustMap], dict[str, str]]:
    """Per vehicle type whose logs hold no force: its map and ``thrust_source``.

    ``shapes`` maps each such type to its logs' base shape; ``free_flight`` its train logs' free-flight
    samples (thrust at scale 1). A type of :data:`PUBLISHED_MAPS` whose logs follow that shape takes the
    published map; every other type the base shape times a scale calibrated on ``free_flight``."""
    maps, sources = {}, {}
    for vtype, shape in shapes.items():
        published = PUBLISHED_MAPS.get(vtype) == shape
        samples = free_flight.get(vtype, ())
        if published and sum(int(s.free.sum()) for s in samples) < MIN_FREE_SAMPLES:
            maps[vtype], sources[vtype] = base_map(shape), SOURCE_PUBLISHED  # nothing to check it on: as published
            continue
        scale, n = calibrate_scale(samples)
        base = base_map(shape)
        label = f"{base.source} x free-flight scale" if published else f"free-flight-scale:{shape}"
        maps[vtype] = replace(base, coef=tuple(scale * c for c in base.coef), n_fit=n, scale=scale, source=label)
        sources[vtype] = SOURCE_PUBLISHED_SCALED if published else SOURCE_FREE_FLIGHT
    return maps, sources


def thrust_source_of(tmap: ThrustMap) -> str:
    """``thrust_source`` label of a map used on a log without forces."""
    if tmap.source.startswith("published"):
        return SOURCE_PUBLISHED_SCALED if "free-flight scale" in tmap.source else SOURCE_PUBLISHED
    return SOURCE_FREE_FLIGHT


def forceless_maps(
    flights: Sequence[tuple], types: Mapping[str, Vehicle], options_for: Callable[[Vehicle], MeasureOptions]
) -> tuple[dict[str, ThrustMap], dict[str, str]]:
    """:func:`pwm_thrust_maps` for the vehicle types of ``flights`` ((FlightEntry, Flight) pairs) whose
    logs hold no force, calibrated on their TRAIN flights (validation and test flights fit nothing);
    ``options_for(vehicle)``: its measurement options (motor lag)."""
    shapes: dict[str, str] = {}
    free: dict[str, list[FreeFlight]] = {}
    for entry, flight in flights:
        for v in entry.vehicles:
            log = flight.logs[v.name]
            if log.thrust_logged:
                continue
            if shapes.setdefault(v.type, log.thrust_shape) != log.thrust_shape:
                raise UserError(f"{log.source}: motor thrust follows {log.thrust_shape}, other logs of type "
                                f"{v.type} follow {shapes[v.type]}; one base map per vehicle type")  # fmt: skip
            if entry.split != "train":
                continue
            others = [(types[o.type].size_m, flight.logs[o.name]) for o in entry.vehicles if o.name != v.name]
            veh = flight.vehicles[v.name]
            free.setdefault(v.type, []).append(FreeFlight(veh, log, options_for(veh),
                                                          free_flight_mask(log, v.ground_z_m, others)))  # fmt: skip
    return pwm_thrust_maps(shapes, free)
