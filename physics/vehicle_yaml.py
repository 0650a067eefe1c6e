"""Custom vehicles from YAML, validated, and the reverse (vehicle -> YAML dict).

File layout (every key is optional when ``base`` names a built-in type, required otherwise)::

    vehicles:
      heavy-lifter:
        base: large-quad            # start from a built-in type and override what follows
        mass_kg: 0.9
        arm_length_m: 0.2
        max_thrust_N: 30
        min_motor_thrust_N: 0.0
        inertia_diag_kgm2: [0.006, 0.006, 0.011]
        torque_to_thrust_m: 0.02
        propeller: {diameter_m: 0.254, chord_m: 0.02, pitch_m: 0.114, n_blades: 2,
                    thrust_coefficient: 0.11, b_v_measured: 4.0e-7}
        frame: {hub_side_m: 0.12, arm_width_m: 0.02, motor_pod_diameter_m: 0.03}
        downwash: {c_ax: 4.9, z0_m: 0.12, c_rad: 25.0}
        kinematics: {max_speed_mps: 1.0, max_accel_mps2: 2.0, max_jerk_mps3: 8.0}  # optional
        tracking: {controller: mellinger, tube_m: 0.045, ...}  # optional: proxplan track-limits output
        motor_time_constant_s: 0.04                                               # optional
    model: {...}                    # optional: a model file's model section (proxplan.physics.model_file),
                                    # not read here: load_model_file applies it

Every error is a :class:`~proxplan.fileio.errors.UserError` naming the file and the key.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from proxplan.fileio import UserError, read_yaml
from proxplan.physics.builtin_vehicles import BUILTIN_VEHICLES
from proxplan.physics.propeller import PropellerSpec
from proxplan.physics.vehicles import DownwashSpec, FrameSpec, KinematicLimits, TrackingMeasurement, Vehicle

_TOP_KEYS = {
    "base", "description", "mass_kg", "arm_length_m", "max_thrust_N", "min_motor_thrust_N",
    "inertia_diag_kgm2", "torque_to_thrust_m", "propeller", "frame", "downwash", "kinematics",
    "motor_time_constant_s", "tracking",
}  # fmt: skip
_POSITIVE = {"mass_kg", "arm_length_m", "max_thrust_N", "torque_to_thrust_m", "motor_time_constant_s"}
_SECTIONS: dict[str, type] = {"propeller": PropellerSpec, "frame": FrameSpec, "downwash": DownwashSpec}
_OPTIONAL_FIELDS = {"min_motor_thrust_N", "description", "motor_time_constant_s"}


def _number(value: Any, where: str, *, positive: bool, allow_none: bool = False, signed: bool = False) -> float | None:
    """Validate a finite number: > 0 if ``positive``, any sign if ``signed``, else >= 0."""
    if value is None and allow_none:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise UserError(f"{where}: expected a number, got {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise UserError(f"{where}: expected a finite number, got {value!r}")
    if positive and value <= 0.0:
        raise UserError(f"{where}: expected a positive number, got {value!r}")
    if not positive and not signed and value < 0.0:
        raise UserError(f"{where}: expected a number >= 0, got {value!r}")
    return value


def _section(cls: type, data: Any, base: Any, where: str) -> Any:
    if not isinstance(data, Mapping):
        raise UserError(f"{where}: expected a mapping, got {type(data).__name__}")
    fields = {f.name: f for f in dataclasses.fields(cls)}
    unknown = set(data) - set(fields)
    if unknown:
        raise UserError(f"{where}: unknown key {sorted(unknown)[0]!r}; expected one of {sorted(fields)}")
    values: dict[str, Any] = {}
    for name, f in fields.items():
        key_where = f"{where}.{name}"
        if name in data:
            raw = data[name]
            if name == "n_blades":
                if isinstance(raw, bool) or not isinstance(raw, int) or raw < 1:
                    raise UserError(f"{key_where}: expected a whole number >= 1, got {raw!r}")
                values[name] = raw
            elif name == "z0_m":
                values[name] = _number(raw, key_where, positive=False, signed=True)
            elif name == "b_v_measured":
                values[name] = _number(raw, key_where, positive=True, allow_none=True)
            else:
                values[name] = _number(raw, key_where, positive=True)
        elif base is not None:
            values[name] = getattr(base, name)
        elif f.default is not dataclasses.MISSING:
            values[name] = f.default
        else:
            raise UserError(f"{where}: missing key {name!r}")
    return cls(**values)


def vehicle_from_dict(name: str, data: Any, *, source: str = "<vehicle>") -> Vehicle:
    """Build and validate one vehicle from its YAML mapping (``source`` names the file)."""
    where = f"{source}: vehicles.{name}"
    if not isinstance(data, Mapping):
        raise UserError(f"{where}: expected a mapping of vehicle parameters")
    unknown = set(data) - _TOP_KEYS
    if unknown:
        raise UserError(f"{where}: unknown key {sorted(unknown)[0]!r}; expected one of {sorted(_TOP_KEYS)}")
    base = None
    if "base" in data:
        base = BUILTIN_VEHICLES.get(str(data["base"]))
        if base is None:
            raise UserError(
                f"{where}.base: unknown vehicle type {data['base']!r}; built-in types are {', '.join(BUILTIN_VEHICLES)}"
            )
    values: dict[str, Any] = {"name": name}
    for key in (
        "mass_kg",
        "arm_length_m",
        "max_thrust_N",
        "torque_to_thrust_m",
        "min_motor_thrust_N",
        "motor_time_constant_s",
    ):
        if key in data:
            values[key] = _number(data[key], f"{where}.{key}", positive=key in _POSITIVE)
        elif base is not None:
            values[key] = getattr(base, key)
        elif key not in _OPTIONAL_FIELDS:
            raise UserError(f"{where}: missing key {key!r}")
    if "inertia_diag_kgm2" in data:
        raw = data["inertia_diag_kgm2"]
        if not isinstance(raw, (list, tuple)) or len(raw) != 3:
            raise UserError(f"{where}.inertia_diag_kgm2: expected a list of 3 positive numbers, got {raw!r}")
        values["inertia_diag_kgm2"] = tuple(
            _number(v, f"{where}.inertia_diag_kgm2[{i}]", positive=True) for i, v in enumerate(raw)
        )
    elif base is not None:
        values["inertia_diag_kgm2"] = base.inertia_diag_kgm2
    else:
        raise UserError(f"{where}: missing key 'inertia_diag_kgm2'")
    for key, cls in _SECTIONS.items():
        if key in data:
            values[key] = _section(cls, data[key], getattr(base, key, None), f"{where}.{key}")
        elif base is not None:
            values[key] = getattr(base, key)
        else:
            raise UserError(f"{where}: missing key {key!r}")
    if "kinematics" in data:
        values["kinematics"] = _section(
            KinematicLimits, data["kinematics"], getattr(base, "kinematics", None), f"{where}.kinematics"
        )
    elif base is not None:
        values["kinematics"] = base.kinematics
    if "tracking" in data:
        values["tracking"] = _tracking(data["tracking"], f"{where}.tracking")
    elif base is not None and "kinematics" not in data:  # the base's limits come with their measurement
        values["tracking"] = base.tracking
    values["description"] = str(data.get("description", f"custom vehicle from {source}"))
    vehicle = Vehicle(**values)
    if vehicle.max_thrust_per_rotor_N <= vehicle.hover_thrust_per_rotor_N:
        raise UserError(
            f"{where}.max_thrust_N: {vehicle.max_thrust_N} N cannot lift {vehicle.mass_kg} kg "
            f"(needs more than {vehicle.weight_N:.3f} N)"
        )
    return vehicle


def _tracking(data: Any, where: str) -> TrackingMeasurement:
    """A :class:`TrackingMeasurement` from its mapping (every field required)."""
    fields = {f.name: f.type for f in dataclasses.fields(TrackingMeasurement)}
    if not isinstance(data, Mapping):
        raise UserError(f"{where}: expected a mapping with keys {', '.join(fields)}")
    unknown = set(data) - set(fields)
    if unknown:
        raise UserError(f"{where}: unknown key {sorted(unknown)[0]!r}; expected {', '.join(fields)}")
    values: dict[str, Any] = {}
    for key, kind in fields.items():
        if key not in data:
            raise UserError(f"{where}: missing key {key!r}")
        if kind == "str":
            values[key] = str(data[key])
        else:
            values[key] = _number(data[key], f"{where}.{key}", positive=False)
    if not 0.0 < values["error_quantile"] <= 1.0:
        raise UserError(f"{where}.error_quantile: expected a number in (0, 1], got {values['error_quantile']!r}")
    return TrackingMeasurement(**values)


def load_vehicle_file(path: str | Path) -> dict[str, Vehicle]:
    """Read a vehicles YAML file into ``{name: Vehicle}``; UserError on any problem."""
    path = Path(path)
    doc = read_yaml(path, what="vehicle file")
    if not isinstance(doc, Mapping) or not isinstance(doc.get("vehicles"), Mapping):
        raise UserError(f"{path}: expected a top-level 'vehicles:' mapping of NAME: parameters")
    unknown = set(doc) - {"vehicles", "model", "format_version"}
    if unknown:
        raise UserError(
            f"{path}: unknown top-level key {sorted(unknown)[0]!r}; expected 'vehicles' and optional 'model' "
            "(a model file, proxplan.physics.model_file)"
        )
    return {str(n): vehicle_from_dict(str(n), d, source=str(path)) for n, d in doc["vehicles"].items()}


def resolve_vehicle(name: str, custom: Mapping[str, Vehicle] | None = None, *, where: str = "") -> Vehicle:
    """A vehicle by type name: custom ones first, then built-ins; UserError for unknown names."""
    if custom and name in custom:
        return custom[name]
    if name in BUILTIN_VEHICLES:
        return BUILTIN_VEHICLES[name]
    known = list(custom or {}) + list(BUILTIN_VEHICLES)
    prefix = f"{where}: " if where else ""
    raise UserError(f"{prefix}unknown vehicle type {name!r}; known types: {', '.join(known)}")


def vehicle_to_yaml_dict(vehicle: Vehicle, *, base: str | None = None) -> dict[str, Any]:
    """The YAML mapping of ``vehicle`` (all parameters; ``base`` recorded when given)."""
    out: dict[str, Any] = {}
    if base is not None:
        out["base"] = base
    out["description"] = vehicle.description
    for key in (
        "mass_kg",
        "arm_length_m",
        "max_thrust_N",
        "min_motor_thrust_N",
        "torque_to_thrust_m",
        "motor_time_constant_s",
    ):
        out[key] = float(getattr(vehicle, key))
    if vehicle.kinematics is not None:
        out["kinematics"] = dataclasses.asdict(vehicle.kinematics)
    if vehicle.tracking is not None:
        out["tracking"] = dataclasses.asdict(vehicle.tracking)
    out["inertia_diag_kgm2"] = [float(v) for v in vehicle.inertia_diag_kgm2]
    for key in _SECTIONS:
        out[key] = {k: v for k, v in dataclasses.asdict(getattr(vehicle, key)).items() if v is not None}
    return out
