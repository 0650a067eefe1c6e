"""The vehicle file: custom vehicle types in YAML, declared (:class:`VehicleFile`), read into
:class:`~proxplan.physics.vehicles.Vehicle`, and the reverse (vehicle -> YAML dict).

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
        rotor_drag: {k_d_Ns2pradm: 1.06e-6, k_z_Ns2pradm: 7.8e-7}   # optional, >= 0 (proxplan.physics.rotor_drag)
        controller: {kp_xy_Npm: 1.2, kd_xy_Nspm: 0.35}  # optional: the gains it flies with, SI
                                    # (proxplan.physics.controller_gains; kp/kd/kR/kw > 0, the rest >= 0)
    model: {...}                    # optional: a model file's model section (proxplan.physics.model_file),
                                    # not read here: load_model_file applies it

Each section model mirrors one dataclass of :mod:`proxplan.physics.vehicles` field for field (a test
checks it): a new vehicle parameter is a field in the dataclass and one declared field here, with its
unit in the name and a description; :func:`build_vehicle` copies every declared field by name.
Without ``rotor_drag`` / ``controller`` a vehicle takes its base's (a Crazyflie with extra mass still
flies the firmware's defaults), or, without a base, RotorPy's Crazyflie rotor drag scaled to its
rotors and the Crazyflie 2.1's firmware gains scaled to its mass and inertia (:data:`DERIVED`); a
partial section overrides only the keys it names.
Every error is a :class:`~proxplan.fileio.errors.UserError` naming the file and the key.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from pathlib import Path
from typing import Annotated, Any

from pydantic import Field, field_validator, model_validator

from proxplan.fileio import (
    FileModel,
    Name,
    NonNegative,
    Number,
    Positive,
    Text,
    UserError,
    Whole,
    missing,
    optional,
    problem,
    read_yaml,
    validate,
)
from proxplan.physics.builtin_vehicles import BUILTIN_VEHICLES, CRAZYFLIE_21
from proxplan.physics.controller_gains import ControllerGains, scaled_gains
from proxplan.physics.propeller import PropellerSpec
from proxplan.physics.rotor_drag import RotorDrag, rotorpy_rotor_drag
from proxplan.physics.vehicles import (
    GRAVITY_MPS2,
    DownwashSpec,
    FrameSpec,
    KinematicLimits,
    TrackingMeasurement,
    Vehicle,
)

# ------------------------------------------------------------------------------------ declared model


class PropellerPart(FileModel):
    """One propeller type (all rotors share it): geometry and static thrust coefficient."""

    diameter_m: Positive = optional("propeller diameter, m")
    chord_m: Positive = optional("blade chord at 75 % radius, m (blade-element theory, S1-4..S1-8)")
    pitch_m: Positive = optional("geometric pitch (advance per revolution), m")
    n_blades: Annotated[Whole, Field(ge=1)] = optional("blades per propeller, -")
    thrust_coefficient: Positive = optional("static C_T of T = C_T rho n^2 D^4 (n in rev/s), -")
    lift_slope_per_rad: Positive = optional("2-D lift-curve slope a, 1/rad (default 5.7; S1 Table 1)")
    tip_loss_factor: Positive = optional("tip loss factor B, - (default 0.9; S1 Table 1)")
    b_v_measured: Positive | None = optional(
        "measured thrust decay coefficient b_v (S0-5), N m^-1 rad^-2 s^3; null or absent: derived "
        "from blade-element theory",
    )


class FramePart(FileModel):
    """Frame geometry projected on the body x-y plane, for the drag integral (S0-3, S0-4)."""

    hub_side_m: Positive = optional("side of the square central hub, m")
    arm_width_m: Positive = optional("width of each arm, m")
    motor_pod_diameter_m: Positive = optional("diameter of the motor pod under each rotor, m")


class DownwashPart(FileModel):
    """Velocity-field parameters of this vehicle as a downwash source (S0-1, S0-2)."""

    c_ax: Positive = optional("axial decay constant of the jet, - (S0-1)")
    z0_m: Number = optional("virtual origin of the jet below the rotor plane, m (S0-1; any sign)")
    c_rad: Positive = optional("radial (Gaussian) decay rate, - (S0-2)")


class KinematicsPart(FileModel):
    """Norm limits the vehicle and its controller track (proxplan track-limits measures them)."""

    max_speed_mps: Positive = optional("largest speed, m/s")
    max_accel_mps2: Positive = optional("largest acceleration, m/s^2")
    max_jerk_mps3: Positive = optional("largest jerk, m/s^3")


class TrackingPart(FileModel):
    """How the kinematic limits and tracking tube were measured (the output of proxplan track-limits;
    every key required)."""

    controller: Text = Field(description="controller flown for the measurement (mellinger or rotorpy)")
    tube_m: NonNegative = Field(description="tracking tube: error quantile + margin, m")
    error_quantile: Annotated[Number, Field(gt=0, le=1)] = Field(description="quantile of the position error, -")
    quantile_error_m: NonNegative = Field(description="that quantile of the position error, m")
    max_error_m: NonNegative = Field(description="largest position error over the course, m")
    margin_m: NonNegative = Field(description="margin added to the quantile, m")
    budget_m: NonNegative = Field(description="largest tube the measurement accepted, m")
    saturation_s: NonNegative = Field(description="motor-saturated time at the kept level, s")
    limited_by: Text = Field(description="what stopped the next faster level")
    course: Text = Field(description="the calibration course flown")
    command: Text = Field(description="the command that made the measurement")
    date: Text = Field(description="date of the measurement")


class RotorDragPart(FileModel):
    """Rotor drag per rotor in RotorPy's form (proxplan.physics.rotor_drag): a rotor spinning at omega
    through air at v (body frame) meets -omega (k_d v_x, k_d v_y, k_z v_z)."""

    k_d_Ns2pradm: NonNegative = optional("in-plane rotor drag k_d, N per (rad/s x m/s)")
    k_z_Ns2pradm: NonNegative = optional("axial (induced-inflow) drag k_z, N per (rad/s x m/s)")


class ControllerPart(FileModel):
    """The gains of the Mellinger law the vehicle flies, SI (proxplan.physics.controller_gains; the
    Crazyflie firmware's ctrlMel position gains are SI already, its attitude gains convert from PWM
    through massThrust): xy = horizontal position and roll / pitch, z = vertical position and yaw."""

    kp_xy_Npm: Positive = optional("horizontal position gain, N/m (firmware kp_xy)")
    kd_xy_Nspm: Positive = optional("horizontal velocity gain, N s/m (firmware kd_xy)")
    ki_xy_Npms: NonNegative = optional("horizontal position integral gain, N/(m s) (firmware ki_xy)")
    i_range_xy_ms: NonNegative = optional("bound of the horizontal position integral, m s")
    kp_z_Npm: Positive = optional("vertical position gain, N/m (firmware kp_z)")
    kd_z_Nspm: Positive = optional("vertical velocity gain, N s/m (firmware kd_z)")
    ki_z_Npms: NonNegative = optional("vertical position integral gain, N/(m s) (firmware ki_z)")
    i_range_z_ms: NonNegative = optional("bound of the vertical position integral, m s")
    kR_xy_Nmprad: Positive = optional("roll / pitch attitude gain, N m/rad")
    kw_xy_Nmsprad: Positive = optional("roll / pitch rate gain, N m s/rad")
    ki_m_xy_Nmprads: NonNegative = optional("roll / pitch attitude integral gain, N m/(rad s)")
    i_range_m_xy_rads: NonNegative = optional("bound of the roll / pitch attitude integral, rad s")
    kR_z_Nmprad: Positive = optional("yaw attitude gain, N m/rad")
    kw_z_Nmsprad: Positive = optional("yaw rate gain, N m s/rad")
    ki_m_z_Nmprads: NonNegative = optional("yaw attitude integral gain, N m/(rad s)")
    i_range_m_z_rads: NonNegative = optional("bound of the yaw attitude integral, rad s")
    kd_omega_rp_Nms2prad: NonNegative = optional("roll / pitch rate-error derivative gain, N m s^2/rad")


SECTIONS: dict[str, tuple[type, type[FileModel]]] = {
    "propeller": (PropellerSpec, PropellerPart),
    "frame": (FrameSpec, FramePart),
    "downwash": (DownwashSpec, DownwashPart),
    "kinematics": (KinematicLimits, KinematicsPart),
    "tracking": (TrackingMeasurement, TrackingPart),
    "rotor_drag": (RotorDrag, RotorDragPart),
    "controller": (ControllerGains, ControllerPart),
}
"""Vehicle sections: key -> (dataclass of :mod:`proxplan.physics.vehicles`, declared part)."""
REQUIRED_WITHOUT_BASE = ("mass_kg", "arm_length_m", "max_thrust_N", "inertia_diag_kgm2", "torque_to_thrust_m",
                         "propeller", "frame", "downwash")  # fmt: skip
"""Keys a vehicle without ``base`` must give (the others have defaults or are optional)."""
DERIVED = ("rotor_drag", "controller")
"""Sections a vehicle without ``base`` may leave out, or give in part: the rest is derived from its
other parameters (:func:`_derived`)."""


def _required_fields(cls: type) -> list[str]:
    return [f.name for f in dataclasses.fields(cls) if f.default is dataclasses.MISSING]


def _if_no_base(schema: dict[str, Any]) -> None:
    """JSON Schema: without ``base`` the required keys and section fields are required."""
    sections = {
        k: {"required": _required_fields(cls)}
        for k, (cls, _) in SECTIONS.items()
        if k != "tracking" and k not in DERIVED
    }
    schema["if"] = {"not": {"required": ["base"]}}
    schema["then"] = {"required": list(REQUIRED_WITHOUT_BASE), "properties": sections}


class VehicleEntry(FileModel, json_schema_extra=_if_no_base):
    """One vehicle type: a built-in ``base`` and the parameters that differ from it, or every parameter."""

    base: Text | None = optional(
        "built-in type to start from (proxplan vehicles lists them); the keys given override its values",
        json_schema_extra={"enum": list(BUILTIN_VEHICLES)},
    )
    description: Text = optional("what this vehicle is")
    mass_kg: Positive = optional("take-off mass, kg")
    arm_length_m: Positive = optional("centre of mass to each motor axis, m (vehicle size L = 2 x arm)")
    max_thrust_N: Positive = optional("largest thrust of all motors together, N")
    min_motor_thrust_N: NonNegative = optional("lowest thrust one motor can hold, N (default 0)")
    inertia_diag_kgm2: tuple[Positive, Positive, Positive] = optional(
        "principal moments of inertia [Jxx, Jyy, Jzz], kg m^2"
    )
    torque_to_thrust_m: Positive = optional("k_t of (S0-14c): yaw torque per unit thrust, m")
    motor_time_constant_s: Positive = optional("first-order motor lag, s (default 0.04)")
    propeller: PropellerPart = optional("the propeller (all rotors share it)")
    frame: FramePart = optional("frame geometry for the drag integral")
    downwash: DownwashPart = optional("velocity-field parameters as a downwash source")
    kinematics: KinematicsPart = optional(
        "trackable speed / acceleration / jerk limits (default: derived from thrust-to-weight)"
    )
    tracking: TrackingPart = optional("how kinematics and the tube were measured (proxplan track-limits)")
    rotor_drag: RotorDragPart = optional("rotor drag coefficients (default: the base's, or RotorPy's scaled)")
    controller: ControllerPart = optional(
        "the controller gains it flies with (default: the base's, or the Crazyflie firmware's scaled)"
    )

    @field_validator("base")
    @classmethod
    def _known_base(cls, value: str | None) -> str | None:
        if value is not None and value not in BUILTIN_VEHICLES:
            raise problem(f"unknown vehicle type {value!r}; built-in types are {', '.join(BUILTIN_VEHICLES)}")
        return value

    @model_validator(mode="after")
    def _complete_without_base(self) -> VehicleEntry:
        base = BUILTIN_VEHICLES.get(self.base) if self.base is not None else None
        for key in REQUIRED_WITHOUT_BASE if base is None else ():
            if key not in self.model_fields_set:
                raise missing(key)
        for key, (cls, _) in SECTIONS.items():
            part = getattr(self, key)
            if key in ("tracking", *DERIVED) or part is None or (base is not None and getattr(base, key) is not None):
                continue
            for name in _required_fields(cls):
                if name not in part.model_fields_set:
                    raise missing(f"{key}.{name}")
        return self


class VehicleFile(FileModel):
    """A vehicle file: custom vehicle types by name (``proxplan plan``'s ``vehicle_file:``, ``--vehicle-file``)."""

    vehicles: dict[Name, VehicleEntry] = Field(description="vehicle types by name (used as 'type:' in scenarios)")
    model: dict[str, Any] | None = optional(
        "a model file's model section: not read through a vehicle file (give the file as model_file)"
    )
    format_version: Whole | None = optional("model-file format version, when this is a model file")


# ------------------------------------------------------------------------------- building vehicles


def _section(cls: type, part: FileModel | None, base: Any) -> Any:
    """The dataclass ``cls`` from the keys given in ``part``, the rest from ``base`` (or the defaults)."""
    given = part.model_dump(exclude_unset=True) if part is not None else {}
    values = {}
    for f in dataclasses.fields(cls):
        if f.name in given:
            values[f.name] = given[f.name]
        elif base is not None:
            values[f.name] = getattr(base, f.name)
        elif f.default is not dataclasses.MISSING:
            values[f.name] = f.default
    return cls(**values)


def build_vehicle(name: str, entry: VehicleEntry, *, source: str, where: str) -> Vehicle:
    """The :class:`Vehicle` of a validated entry; ``where`` (``FILE: vehicles.NAME``) labels the one
    check that needs the whole vehicle (enough thrust to hover)."""
    base = BUILTIN_VEHICLES.get(entry.base) if entry.base is not None else None
    given = entry.model_fields_set
    values: dict[str, Any] = {"name": name}
    for f in dataclasses.fields(Vehicle):
        key = f.name
        if key in ("name", "sources", "description"):
            continue
        if key in DERIVED:
            continue  # after the parameters they derive from
        if key in SECTIONS:
            cls = SECTIONS[key][0]
            if key in given:
                values[key] = _section(cls, getattr(entry, key), getattr(base, key, None))
            elif base is not None and not (key == "tracking" and "kinematics" in given):
                values[key] = getattr(base, key)  # the base's limits come with their measurement
        elif key in given:
            values[key] = getattr(entry, key)
        elif base is not None:
            values[key] = getattr(base, key)
    for key in DERIVED:
        default = getattr(base, key) if base is not None else _derived(key, values)
        values[key] = _section(SECTIONS[key][0], getattr(entry, key), default) if key in given else default
    values["description"] = entry.description if "description" in given else f"custom vehicle from {source}"
    vehicle = Vehicle(**values)
    if vehicle.max_thrust_per_rotor_N <= vehicle.hover_thrust_per_rotor_N:
        raise UserError(
            f"{where}.max_thrust_N: {vehicle.max_thrust_N} N cannot lift {vehicle.mass_kg} kg "
            f"(needs more than {vehicle.weight_N:.3f} N)"
        )
    default_gains = base.controller if base is not None else _derived("controller", values)
    _check_hover_loop(vehicle, entry, default_gains, where)
    return vehicle


def _check_hover_loop(vehicle: Vehicle, entry: VehicleEntry, default: ControllerGains, where: str) -> None:
    """UserError when the vehicle's own hover loop (its controller linearised about hover, no jet:
    :mod:`proxplan.physics.hover_loop`) is not damped, naming the gain of the file that does it:
    the given gain whose default value (the base's, else the scaled firmware gains) alone makes it
    damped again (else every gain the file gives)."""
    from proxplan.physics.hover_loop import loop_matrices, loop_poles

    def growth(v: Vehicle) -> tuple[float, float]:
        poles = loop_poles(loop_matrices(v))
        return float(poles.growth_ps[0]), float(poles.frequency_hz[0])

    rate, freq = growth(vehicle)
    if rate < 0.0:
        return
    given = sorted(entry.controller.model_fields_set) if entry.controller is not None else []
    culprits = [
        k for k in given
        if growth(dataclasses.replace(vehicle, controller=dataclasses.replace(vehicle.controller, **{k: getattr(default, k)})))[0] < 0.0
    ]  # fmt: skip
    named = culprits or given
    if named:
        keys = ", ".join(f"controller.{k} = {getattr(vehicle.controller, k):g}" for k in named)
        fix = (
            f"with the default {getattr(default, named[0]):g} it is damped"
            if culprits and len(named) == 1
            else "expected gains that keep every pole of the loop in the left half-plane"
        )
        where_key = f"{where}.controller.{named[0]}" if len(named) == 1 else f"{where}.controller"
    else:
        keys, fix, where_key = "its parameters", "give it gains for its mass and inertia (controller:)", where
    raise UserError(
        f"{where_key}: {keys} makes the vehicle's own hover loop unstable (rightmost pole {rate:+.3f} 1/s at "
        f"{freq:.2f} Hz, linearised Mellinger law, proxplan.physics.hover_loop); {fix}"
    )


def _derived(key: str, values: dict[str, Any]) -> Any:
    """Rotor drag or controller gains of a vehicle without a base (:data:`DERIVED`)."""
    if key == "rotor_drag":
        k1 = values["propeller"].k1_Ns2prad2
        return rotorpy_rotor_drag(k1, (values["mass_kg"] * GRAVITY_MPS2 / 4.0 / k1) ** 0.5)
    cf = CRAZYFLIE_21
    return scaled_gains(cf.controller, cf.mass_kg, cf.inertia_diag_kgm2, values["mass_kg"], values["inertia_diag_kgm2"])


def build_vehicles(entries: Mapping[str, VehicleEntry], *, source: str, key: str = "vehicles") -> dict[str, Vehicle]:
    """Every vehicle of a validated ``vehicles:`` mapping (``key`` is its key path in the file)."""
    return {n: build_vehicle(n, e, source=source, where=f"{source}: {key}.{n}") for n, e in entries.items()}


def vehicle_from_dict(name: str, data: Any, *, source: str = "<vehicle>") -> Vehicle:
    """Build and validate one vehicle from its YAML mapping (``source`` names the file)."""
    entry = validate(VehicleEntry, data, label=source, at=("vehicles", name))
    return build_vehicle(name, entry, source=source, where=f"{source}: vehicles.{name}")


def load_vehicle_file(path: str | Path) -> dict[str, Vehicle]:
    """Read a vehicles YAML file into ``{name: Vehicle}``; UserError on any problem."""
    path = Path(path)
    doc = validate(VehicleFile, read_yaml(path, what="vehicle file"), label=str(path))
    return build_vehicles(doc.vehicles, source=str(path))


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
    for key in ("propeller", "frame", "downwash", "rotor_drag", "controller"):
        out[key] = {k: v for k, v in dataclasses.asdict(getattr(vehicle, key)).items() if v is not None}
    return out
