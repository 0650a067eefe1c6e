r"""Loading a manifest's flights and measuring them (issue 35 split from :mod:`proxplan.identify.data`):
every vehicle log cleaned, its thrust measured (PWM/Vbat map or the logged thrust, through the motor lag
when the logs hold commands) and its disturbance measured (S0-11, S0-13) into :class:`proxplan.identify.data.Unit`\ s.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from proxplan.fileio import UserError
from proxplan.identify.data import CEILING_BIT, FLOOR_BIT, IdentifyOptions, Model, Unit, predict, progress_bar
from proxplan.identify.flightlog import Flight, FlightEntry, Manifest, load_flight
from proxplan.identify.measure import MeasureOptions, kinematic_thrust_z_N, measure_log, smoothed_like_measurement
from proxplan.identify.pwm_thrust import forceless_maps, pwm_limits, thrust_source_of
from proxplan.identify.thrust_map import (
    CEILING,
    FLOOR,
    IN_RANGE,
    MotorSamples,
    ThrustMap,
    delivered_log_limits,
    delivered_thrust_N,
    fit_thrust_maps,
    motor_limits,
)
from proxplan.identify.vehicle_log import VehicleLog, interpolate_position_m
from proxplan.physics import ModelOptions, Vehicle


@dataclass(frozen=True)
class LoadedData:
    """Every flight of a manifest, measured: units, exclusions, vehicle types, thrust maps, notes."""

    units: list[Unit]
    exclusions: dict  # flight -> vehicle -> counts (+ kept_samples, saturated_samples, thrust_source)
    types: dict[str, Vehicle]  # vehicle type name -> Vehicle
    thrust_maps: dict[str, ThrustMap]  # vehicle type -> PWM/Vbat thrust map used for the measurement
    notes: list[str]  # said once each (e.g. a fallback to the commanded u[N])
    logs: dict = field(default_factory=dict)  # (flight, vehicle name) -> (Vehicle, cleaned log with the
    # thrust the measurement takes before any motor lag): for proxplan.identify.motor_check


def measure_options_for(options: MeasureOptions, vehicle: Vehicle, motor_thrust: str) -> MeasureOptions:
    """The measurement options of one vehicle: a log of COMMANDED motor thrust (``motor_thrust``, the
    manifest's key) reaches the air through the motors' first-order lag, so (S0-11, S0-14) use the lagged
    command (:func:`proxplan.identify.measure.motor_lag_compensated_N`) with the vehicle's own
    ``motor_time_constant_s`` (or the explicit ``options.motor_time_constant_s``); a log of DELIVERED
    thrust, or ``options.motor_lag`` False, is used as it is."""
    if motor_thrust != "commanded" or not options.motor_lag:
        return replace(options, motor_time_constant_s=None)
    return replace(options, motor_time_constant_s=options.motor_time_constant_s or vehicle.motor_time_constant_s)


def _motor_samples(log: VehicleLog) -> MotorSamples:
    assert log.motor_pwm is not None and log.vbat_V is not None
    return MotorSamples(commanded_N=log.motor_thrust_N, pwm=log.motor_pwm, vbat_V=log.vbat_V)


def load_units(
    manifest: Manifest,
    *,
    options: IdentifyOptions = IdentifyOptions(),
    thrust_maps: Mapping[str, ThrustMap] | None = None,
    thrust_coefficient_samples: bool = True,
) -> LoadedData:
    """Load, check and measure every flight of ``manifest``.

    The motor thrust in S0-11/S0-13 is the DELIVERED one (:mod:`proxplan.identify.thrust_map`): from PWM and
    Vbat through the per-type map (``thrust_maps``, or fitted here on the manifest's TRAIN flights),
    capped at the motor's maximum. Vehicles whose logs hold no PWM/Vbat (or whose type has no map)
    use the logged u[N] as is; a note says so once per type. ``thrust_coefficient_samples=False``
    skips the seed-001 per-sample regressors (only identify's thrust-coefficient summary uses them).
    """
    from scipy.spatial.transform import Rotation

    from proxplan.identify.formats import read_aligned
    from proxplan.identify.thrust_rls import thrust_samples
    from proxplan.physics import load_vehicle_file, resolve_vehicle

    def reader(v):  # any format (CSV, uSD, bag, ULog), its clock on the flight's (identify.formats.align)
        return read_aligned(v, manifest.format)

    custom = load_vehicle_file(manifest.vehicles_file) if manifest.vehicles_file else None
    types: dict[str, Vehicle] = {}
    exclusions: dict[str, dict] = {}
    flights: list[tuple[FlightEntry, Flight]] = []
    for entry in progress_bar(manifest.flights, "load", options.progress):
        vehicles = {}
        for v in entry.vehicles:
            vehicles[v.name] = types.setdefault(
                v.type, resolve_vehicle(v.type, custom, where=f"{manifest.path}: flight {entry.name}: {v.name}.type")
            )
        lags = {n: measure_options_for(options.measure, veh, manifest.motor_thrust).motor_time_constant_s
                for n, veh in vehicles.items()}  # fmt: skip
        flights.append((entry, load_flight(entry, vehicles, options=manifest.quality, reader=reader,
                                           motor_time_constants_s=lags)))  # fmt: skip
    if thrust_maps is None:
        per_type: dict[str, list[MotorSamples]] = {}
        for entry, flight in flights:
            if entry.split == "train":
                for v in entry.vehicles:
                    if flight.logs[v.name].has_pwm:
                        per_type.setdefault(v.type, []).append(_motor_samples(flight.logs[v.name]))
        thrust_maps = fit_thrust_maps(per_type)
        if any(not log.thrust_logged for _, fl in flights for log in fl.logs.values()):  # PWM-only logs (uSD, ...)
            thrust_maps |= forceless_maps(
                flights, types, lambda veh: measure_options_for(options.measure, veh, manifest.motor_thrust)
            )[0]
    notes: list[str] = []
    units = []
    logs: dict[tuple[str, str], tuple[Vehicle, VehicleLog]] = {}
    measured_with: dict[tuple[str, str], MeasureOptions] = {}
    for entry, flight in progress_bar(flights, "measure", options.progress):
        exclusions[entry.name] = {}
        types_of = {v.name: v.type for v in entry.vehicles}
        for v in entry.vehicles:
            log = flight.logs[v.name]
            tmap = thrust_maps.get(v.type)
            n_sat = n_floor = 0
            source, limit_bits = "logged_u", None
            if not log.thrust_logged:  # no force logged: the type's PWM*Vbat map gives it (identify.pwm_thrust)
                if tmap is None:
                    raise UserError(f"{log.source}: the log holds no motor force and the model has no PWM thrust "
                                    f"map for type {v.type}; identify it on such logs first")  # fmt: skip
                lim = pwm_limits(log.motor_pwm)
                limit_bits = (np.any(lim == CEILING, axis=1) * CEILING_BIT
                              + np.any(lim == FLOOR, axis=1) * FLOOR_BIT).astype(np.uint8)  # fmt: skip
                n_sat, n_floor = int(np.sum(limit_bits & CEILING_BIT > 0)), int(np.sum(limit_bits & FLOOR_BIT > 0))
                log = replace(log, motor_thrust_N=tmap.thrust_N(log.motor_pwm, log.vbat_V))
                source = thrust_source_of(tmap)
            elif log.has_pwm and tmap is not None and tmap.usable:
                motor = _motor_samples(log)
                lim = motor_limits(tmap, motor, dt_s=float(np.median(np.diff(log.t_s))) if len(log) > 1 else 0.01)
                if manifest.motor_thrust == "delivered":  # u[N] is the rotors' force: replaced only where no motor
                    veh = flight.vehicles[v.name]  # gives it (thrust_map.delivered_log_limits)
                    lim = delivered_log_limits(lim, motor, min_thrust_N=veh.min_motor_thrust_N,
                                               max_thrust_N=veh.max_thrust_per_rotor_N)  # fmt: skip
                    bits = np.where(lim != IN_RANGE, lim, pwm_limits(log.motor_pwm))
                else:
                    bits = lim
                limit_bits = (np.any(bits == CEILING, axis=1) * CEILING_BIT
                              + np.any(bits == FLOOR, axis=1) * FLOOR_BIT).astype(np.uint8)  # fmt: skip
                n_sat, n_floor = int(np.sum(limit_bits & CEILING_BIT > 0)), int(np.sum(limit_bits & FLOOR_BIT > 0))
                log = replace(log, motor_thrust_N=delivered_thrust_N(tmap, motor, lim))
                source = "pwm"
            else:
                why = "its logs hold no PWM/Vbat columns" if not log.has_pwm else "no thrust map for its type"
                if log.has_pwm and tmap is not None:
                    why = (f"its u[N] follows no static map of PWM*Vbat (R2 {tmap.r2:.2f} on "
                           f"{tmap.inlier_fraction:.0%} inliers, {'rising' if tmap.monotonic else 'not rising'}): "
                           "it is not the desired force")  # fmt: skip
                note = (f"{v.type}: motor thrust = the logged u[N] ({why}); saturated motors are not "
                        "detected, the measured disturbance is wrong where a motor saturates")  # fmt: skip
                if note not in notes:
                    notes.append(note)
            exclusions[entry.name][v.name] = flight.exclusions[v.name].to_dict() | {
                "kept_samples": len(log), "saturated_samples": n_sat, "floored_samples": n_floor,
                "thrust_source": source, "scored": v.score} | dict(flight.alignment.get(v.name, {}))  # fmt: skip
            veh = flight.vehicles[v.name]
            logs[(entry.name, v.name)] = (veh, log)
            mopts = measure_options_for(options.measure, veh, manifest.motor_thrust)
            held = dict(mopts.command_interpolation_by_type)
            if v.type in held:  # how this type's logged command runs between samples (identify.command_check)
                mopts = replace(mopts, command_interpolation=held[v.type])
            measured_with[(entry.name, v.name)] = mopts
            meas = measure_log(veh, log, options=mopts)
            z_b = Rotation.from_quat(log.quat_xyzw).apply(np.array([0.0, 0.0, 1.0]))
            others = [o for o in entry.vehicles if o.name != v.name]
            units.append(
                Unit(
                    flight=entry.name,
                    split=entry.split,
                    name=v.name,
                    type=v.type,
                    t_s=log.t_s,
                    velocity_mps=log.velocity_mps,
                    height_above_ground_m=log.position_m[:, 2] - v.ground_z_m,
                    thrust_z_N=log.motor_thrust_N.sum(axis=1) * z_b[:, 2],
                    thrust_kin_z_N=kinematic_thrust_z_N(veh, log, options=options.measure),
                    source_types=tuple(types_of[o.name] for o in others),
                    source_offsets_m=tuple(  # smoothed like the measured wrench (measure.smoothed_like_measurement)
                        smoothed_like_measurement(
                            log, log.position_m - interpolate_position_m(flight.logs[o.name], log.t_s), options=mopts
                        )
                        for o in others
                    ),
                    force_N=meas.force_N,
                    torque_Nm=meas.torque_Nm,
                    thrust=thrust_samples(
                        flight.vehicles[v.name], log.quat_xyzw, log.accel_mps2, log.velocity_mps, log.motor_thrust_N
                    )
                    if thrust_coefficient_samples
                    else None,
                    scored=v.score,
                    position_m=log.position_m,
                    planes=manifest.planes,
                    motor_limit=limit_bits,
                )
            )
    if options.smoothed_prediction:
        prior = Model(
            vehicles=types, options=ModelOptions(field_form=options.field_form, stack_shielding=options.stack_shielding)
        )
        units = [smoothing_of_prediction(u, logs[(u.flight, u.name)][1], prior, measured_with[(u.flight, u.name)])
                 for u in units]  # fmt: skip
    return LoadedData(units=units, exclusions=exclusions, types=types, thrust_maps=dict(thrust_maps), notes=notes,
                      logs=logs)  # fmt: skip


def smoothing_of_prediction(unit: Unit, log: VehicleLog, prior: Model, options: MeasureOptions) -> Unit:
    """``unit`` with what the measurement's smoothing does to the ``prior`` model's wrench, S(p) - p
    (:attr:`Unit.smoothing_force_N`, :attr:`Unit.smoothing_torque_Nm`; ``log`` the unit's full-rate log, ``options``
    the measurement's): the measured wrench is the smoothed true wrench (the Savitzky-Golay fit over
    ``options.window_s``, :func:`proxplan.identify.measure.measure_log`), and where a vehicle crosses a jet
    faster than the window, S(p) differs from p (a peak is flattened and widened). A prediction that
    leaves this out leaves a residual that follows the prediction's curvature in time, which a delayed
    copy of the base model, or any lagged feature, then fits (on the discovery benchmark's clean sets,
    S(p) - p explained 10-63 % of the F_z residual with a coefficient of 0.98-1.01). The smoothing is
    linear, so S(p) - p is evaluated once, on the prior model (the base model of the unit's types, no
    effect): the model a fit ends on differs from it by a few percent, and the smoothing of that
    difference is a few percent of this correction. A unit with no source gets none (its base wrench is 0)."""
    if not unit.source_types:
        return unit
    force, torque = predict(unit, prior)
    return replace(unit, smoothing_force_N=smoothed_like_measurement(log, force, options=options) - force,
                   smoothing_torque_Nm=smoothed_like_measurement(log, torque, options=options) - torque)  # fmt: skip


def measurement_summary(thrust_maps: dict, exclusions: dict, notes: list[str]) -> dict[str, Any]:
    """JSON of the thrust measurement: maps per type, notes, saturated samples per vehicle NAME."""
    per: dict[str, dict[str, Any]] = {}
    for per_flight in exclusions.values():
        for name, e in per_flight.items():
            d = per.setdefault(name, {"saturated_samples": 0, "floored_samples": 0, "n_samples": 0,
                                      "thrust_source": e["thrust_source"]})  # fmt: skip
            d["saturated_samples"] += e["saturated_samples"]
            d["floored_samples"] += e.get("floored_samples", 0)
            d["n_samples"] += e["kept_samples"]
    for d in per.values():
        d["saturated_fraction"] = d["saturated_samples"] / d["n_samples"] if d["n_samples"] else 0.0
        d["floored_fraction"] = d["floored_samples"] / d["n_samples"] if d["n_samples"] else 0.0
    return {"thrust_maps": {t: m.to_dict() for t, m in thrust_maps.items()}, "saturation": per, "notes": list(notes)}
