"""Scenario YAML loading and validation (DESIGN.md section 4) into frozen dataclasses.

Frame: world, z up, metres. A scenario file::

    # what this scenario tests
    name: battery-swap
    vehicle_file: my_vehicles.yaml              # optional, resolved relative to this file
    model_file: calibrated.yaml                 # optional calibrated model (proxplan identify --save-model):
                                                # its vehicles override same-named types, its effects
                                                # between vehicles are applied (proxplan.physics.model_file)
    model: {field_form: inverse-z,              # optional disturbance-model options (override model_file's;
            stack_shielding: 1.0,               #   stack_shielding: eta of proxplan.physics.stack, 0..3)
            effects: [{name: near_field, params: {amplitude: 0.5}}]}   # added to model_file's
    workspace: {min: [-3, -3, 0], max: [3, 3, 4]}
    obstacles: [{min: [1, -0.5, 0], max: [1.5, 0.5, 2]}]          # optional axis-aligned boxes
    limits: {authority_fraction: 0.4, min_separation_m: 0.3,       # optional
             invalid_zone_rule: conservative, obstacle_margin_m: 0.05, time_horizon_s: 40}
    vehicles:
      carrier: {type: large-quad, start: [0, 0, 1.5], hover: true}
      shuttle: {type: small-quad, start: [2, 1, 2.5], dock: {with: carrier, offset: [0, 0, 0.4]}}
      other:   {type: small-quad, start: [-2, 0, 1], goal: [2, 0, 1], max_speed_mps: 1.0}

Every mistake raises :class:`proxplan.fileio.errors.UserError` with ``FILE: KEY: what was expected``.
"""

from __future__ import annotations

import copy
import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from proxplan.fileio import UserError, read_yaml
from proxplan.physics import (
    DEFAULT_TRACKING_TUBE_M,
    VALIDITY_FACTOR_L,
    CalibratedModel,
    Effect,
    KinematicLimits,
    Vehicle,
)

TOP_KEYS = (
    "name",
    "description",
    "vehicle_file",
    "model_file",
    "model",
    "workspace",
    "obstacles",
    "limits",
    "vehicles",
)
LIMIT_KEYS = (
    "authority_fraction",
    "min_separation_m",
    "invalid_zone_rule",
    "obstacle_margin_m",
    "time_horizon_s",
    "tracking_margin_m",
)
VEHICLE_KEYS = (
    "type",
    "start",
    "goal",
    "hover",
    "dock",
    "max_speed_mps",
    "max_accel_mps2",
    "max_jerk_mps3",
)
TRACKING_MARGIN_M = DEFAULT_TRACKING_TUBE_M
MAX_VEHICLES = 1000  # largest swarm a scenario may hold (the planners' limit)
"""Tube radius, m, of :class:`Limits` built without vehicles (a scenario file without
``limits.tracking_margin_m`` takes :func:`scenario_tube_m` of its vehicles instead)."""


def scenario_tube_m(tasks: Mapping[str, VehicleTask]) -> float:
    """The tube of a scenario whose limits do not set one, m: the largest tracking tube of its
    vehicles' types (``Vehicle.tracking_tube_m``, measured per type by ``proxplan track-limits``).
    Planner and verifier apply one tube per scenario; the largest covers every vehicle."""
    return max(float(t.vehicle.tracking_tube_m) for t in tasks.values())


DOCK_APPROACH_MARGIN_M = 0.1  # a dock approach point lies this far beyond the invalid zone, m
INVALID_ZONE_RULES = ("conservative", "model", "forbid")
"""How the planner treats 0 < dz <= 3 L of a source where the field model is not valid (S0 II-A):
``conservative`` (default) uses the cost map's conservative cutoff there; ``model`` uses the
model's extrapolated numbers; ``forbid`` keeps targets out of the whole invalid cylinder."""


@dataclass(frozen=True)
class Box:
    """Axis-aligned box obstacle, world frame: corners ``min_m`` (3,) and ``max_m`` (3,), m."""

    min_m: np.ndarray
    max_m: np.ndarray
    name: str = ""

    def contains(self, point_m: np.ndarray, *, margin_m: float = 0.0) -> bool:
        """True when ``point_m`` (3,) lies inside the box grown by ``margin_m`` on every side."""
        p = np.asarray(point_m, dtype=float)
        return bool(np.all(p >= self.min_m - margin_m) and np.all(p <= self.max_m + margin_m))


@dataclass(frozen=True)
class Limits:
    """Scenario-wide limits.

    ``authority_fraction``: cap on every vehicle's authority usage (DESIGN.md s. 3), -.
    ``min_separation_m``: minimum centre-to-centre distance of any two vehicles, m (the planner also
    keeps at least the sum of the two body radii, arm + propeller radius; dock pairs are exempt
    at their dock).
    ``invalid_zone_rule``: one of :data:`INVALID_ZONE_RULES`.
    ``obstacle_margin_m``: extra inflation of obstacles beyond the vehicle's body radius, m.
    ``time_horizon_s``: longest plan the sampler searches, s.
    ``tracking_margin_m``: the tube, m: how far a vehicle may be off its plan when flown closed-loop.
    Planner and verifier add it to the separation, to the cut-off radius and to the horizontal and
    vertical extent of the invalid zone. A scenario file without it takes the largest measured tube
    of its vehicle types (:func:`scenario_tube_m`, docs/flying.md).
    """

    authority_fraction: float = 0.5
    min_separation_m: float = 0.25
    invalid_zone_rule: str = "conservative"
    obstacle_margin_m: float = 0.05
    time_horizon_s: float = 60.0
    tracking_margin_m: float = TRACKING_MARGIN_M


@dataclass(frozen=True)
class VehicleTask:
    """One vehicle of a scenario: its type, start and what it must do (goal, hover or dock).

    Positions are world-frame centres of mass, m. ``goal_m`` is None for hover and dock tasks (the
    dock goal follows from the other vehicle's final position plus ``dock_offset_m``).
    """

    name: str
    type_name: str
    vehicle: Vehicle
    start_m: np.ndarray
    goal_m: np.ndarray | None
    hover: bool
    dock_with: str | None
    dock_offset_m: np.ndarray | None
    max_speed_mps: float
    max_accel_mps2: float
    max_jerk_mps3: float

    @property
    def kinematic_limits(self) -> KinematicLimits:
        """This task's speed / acceleration / jerk limits (the vehicle's, or the scenario's override)."""
        return KinematicLimits(self.max_speed_mps, self.max_accel_mps2, self.max_jerk_mps3)

    @property
    def body_radius_m(self) -> float:
        """Radius of the disc that holds the frame and propellers: arm + propeller radius, m."""
        return self.vehicle.body_radius_m


@dataclass(frozen=True)
class Scenario:
    """A validated scenario. ``vehicles`` keeps the order of the file; ``spec`` is the parsed YAML."""

    name: str
    source_path: str | None
    workspace_min_m: np.ndarray
    workspace_max_m: np.ndarray
    obstacles: tuple[Box, ...]
    limits: Limits
    vehicles: dict[str, VehicleTask]
    spec: dict = field(default_factory=dict, compare=False)
    field_form: str | None = None  # disturbance-model field form ("inverse-z" or "printed"), None = default
    load_notes: tuple[str, ...] = ()  # things the user should know about how the file was read
    effects: tuple[Effect, ...] = ()  # effects between vehicles applied by maps, planner, verifier
    stack_shielding: float | None = None  # eta of proxplan.physics.stack (-), None = the model default

    @property
    def model_options(self):
        """The disturbance-model options (:class:`proxplan.physics.ModelOptions`) this scenario asks for:
        field form and stack shielding (its own ``model:`` section, else its model file's)."""
        from proxplan.physics import ModelOptions

        values: dict[str, Any] = {}
        if self.field_form:
            values["field_form"] = self.field_form
        if self.stack_shielding is not None:
            values["stack_shielding"] = self.stack_shielding
        return ModelOptions(**values)

    def to_spec(self) -> dict:
        """The normalised, self-contained scenario mapping (every default filled in, no file
        references; vehicle types by name, their parameters travel with the plan): what plan.json
        stores as ``scenario_spec`` and :func:`scenario_from_dict` reads back."""
        from proxplan.physics import FIELD_FORMS, effects_to_list

        vehicles: dict[str, dict] = {}
        for name, task in self.vehicles.items():
            entry: dict[str, Any] = {"type": task.type_name, "start": task.start_m.tolist()}
            if task.goal_m is not None:
                entry["goal"] = task.goal_m.tolist()
            elif task.hover:
                entry["hover"] = True
            else:
                entry["dock"] = {"with": task.dock_with, "offset": np.asarray(task.dock_offset_m).tolist()}
            entry.update(
                max_speed_mps=task.max_speed_mps, max_accel_mps2=task.max_accel_mps2, max_jerk_mps3=task.max_jerk_mps3
            )
            vehicles[name] = entry
        lim = self.limits
        return {
            "name": self.name,
            "model": {
                "field_form": self.field_form or FIELD_FORMS[0],
                **({"stack_shielding": self.stack_shielding} if self.stack_shielding is not None else {}),
                **({"effects": effects_to_list(self.effects)} if self.effects else {}),
            },
            "workspace": {"min": self.workspace_min_m.tolist(), "max": self.workspace_max_m.tolist()},
            "obstacles": [
                {"min": b.min_m.tolist(), "max": b.max_m.tolist(), **({"name": b.name} if b.name else {})}
                for b in self.obstacles
            ],
            "limits": {
                "authority_fraction": lim.authority_fraction,
                "min_separation_m": lim.min_separation_m,
                "invalid_zone_rule": lim.invalid_zone_rule,
                "obstacle_margin_m": lim.obstacle_margin_m,
                "time_horizon_s": lim.time_horizon_s,
                "tracking_margin_m": lim.tracking_margin_m,
            },
            "vehicles": vehicles,
        }

    def final_position_m(self, name: str) -> np.ndarray:
        """Where vehicle ``name`` ends, world frame (3,), m (follows dock chains)."""
        task = self.vehicles[name]
        if task.goal_m is not None:
            return task.goal_m
        if task.hover:
            return task.start_m
        assert task.dock_with is not None and task.dock_offset_m is not None  # goal, hover or dock
        return self.final_position_m(task.dock_with) + task.dock_offset_m

    def dock_geometry(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """(approach point A (3,), dock point D (3,)), world frame, m, of a docking vehicle.

        A lies on the dock axis (the offset direction from the target) beyond the invalid zone of
        whichever vehicle is above: 3 L of that vehicle plus ``DOCK_APPROACH_MARGIN_M``; for mostly
        horizontal offsets it lies 0.5 m further out than the dock point.
        """
        task = self.vehicles[name]
        if task.dock_with is None or task.dock_offset_m is None:
            raise ValueError(f"vehicle {name!r} does not dock")
        target = self.vehicles[task.dock_with]
        p_target = self.final_position_m(task.dock_with)
        off = np.asarray(task.dock_offset_m, dtype=float)
        d = p_target + off
        n = float(np.linalg.norm(off))
        u: np.ndarray = off / n if n > 0 else np.array([0.0, 0.0, 1.0])
        if abs(u[2]) >= 0.5:
            upper = task.vehicle if off[2] > 0 else target.vehicle
            reach = max(n + 0.3, (VALIDITY_FACTOR_L * upper.size_m + DOCK_APPROACH_MARGIN_M) / abs(u[2]))
        else:
            reach = n + 0.5
        a = p_target + u * reach
        a = np.clip(
            a, self.workspace_min_m + task.vehicle.body_radius_m, self.workspace_max_m - task.vehicle.body_radius_m
        )
        return a, d

    def dock_order(self) -> list[str]:
        """Vehicle names with every dock target before the vehicles docking to it (file order kept)."""
        done: list[str] = []
        for first in self.vehicles:
            chain: list[str] = []
            name: str | None = first
            while name is not None and name not in done and name not in chain:
                chain.append(name)
                name = self.vehicles[name].dock_with
            done.extend(reversed(chain))
        return done


# --------------------------------------------------------------------------------------------
# parsing helpers


def _vec3(value: Any, where: str) -> np.ndarray:
    if (
        not isinstance(value, (list, tuple))
        or len(value) != 3
        or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)
        or not all(math.isfinite(float(v)) for v in value)
    ):
        raise UserError(f"{where}: expected a list of 3 finite numbers [x, y, z] in metres, got {value!r}")
    return np.array([float(v) for v in value])


def _positive(value: Any, where: str, *, upper: float | None = None) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value <= 0:
        raise UserError(f"{where}: expected a positive number, got {value!r}")
    if upper is not None and value > upper:
        raise UserError(f"{where}: expected a number in (0, {upper:g}], got {value!r}")
    return float(value)


def _mapping(value: Any, where: str, what: str) -> Mapping:
    if not isinstance(value, Mapping):
        raise UserError(f"{where}: expected a mapping ({what}), got {type(value).__name__}")
    return value


def _unknown(data: Mapping, allowed: tuple[str, ...], where: str) -> None:
    for key in data:
        if key not in allowed:
            raise UserError(f"{where}.{key}: unknown key; expected one of: {', '.join(allowed)}")


def _box(data: Any, where: str) -> Box:
    data = _mapping(data, where, "{min: [x, y, z], max: [x, y, z]}")
    _unknown(data, ("min", "max", "name"), where)
    for key in ("min", "max"):
        if key not in data:
            raise UserError(f"{where}.{key}: missing; expected {{min: [x, y, z], max: [x, y, z]}} in metres")
    lo, hi = _vec3(data["min"], f"{where}.min"), _vec3(data["max"], f"{where}.max")
    if np.any(hi <= lo):
        raise UserError(f"{where}: expected max > min on every axis, got min {lo.tolist()} max {hi.tolist()}")
    return Box(min_m=lo, max_m=hi, name=str(data.get("name", "")))


def _relative_file(doc: Mapping, key: str, path: Path | None, label: str, what: str) -> Path | None:
    """The file named by ``doc[key]`` (relative to the scenario file), checked to exist; None if absent."""
    if key not in doc:
        return None
    value = doc[key]
    if not isinstance(value, str) or not value:
        raise UserError(f"{label}: {key}: expected a path to {what}, got {value!r}")
    base = path.parent if path is not None else Path.cwd()
    file = (base / value).resolve()
    if not file.exists():
        raise UserError(f"{label}: {key}: file {file} does not exist (paths are relative to the scenario file)")
    return file


def _vehicle_types(doc: Mapping, path: Path | None, label: str) -> dict[str, Vehicle]:
    vfile = _relative_file(doc, "vehicle_file", path, label, "a vehicles YAML file")
    if vfile is None:
        return {}
    from proxplan.physics import load_vehicle_file

    return load_vehicle_file(vfile)


def _model_file(doc: Mapping, path: Path | None, label: str) -> CalibratedModel | None:
    mfile = _relative_file(doc, "model_file", path, label, "a model file (identify --save-model)")
    if mfile is None:
        return None
    from proxplan.physics import load_model_file

    return load_model_file(mfile)


def _model_notes(model: CalibratedModel | None, label: str) -> list[str]:
    if model is None:
        return []
    from proxplan.physics import target_only_notes

    return [*model.notes, *target_only_notes(model, label)]


def _unmapped(effects: tuple[Effect, ...], label: str) -> list[str]:
    from proxplan.costmaps import unmapped_effect_names

    names = unmapped_effect_names(effects)
    if not names:
        return []
    return [
        f"{label}: model effects {', '.join(names)} make the jet depend on azimuth: cost maps and the planner leave "
        "them out, verify and simulate apply them"
    ]


def _vehicle_file_notes(doc: Mapping, path: Path | None) -> list[str]:
    if "vehicle_file" not in doc:
        return []
    from proxplan.physics import vehicle_file_notes

    base = path.parent if path is not None else Path.cwd()
    return vehicle_file_notes((base / doc["vehicle_file"]).resolve())


def _task(name: str, data: Any, where: str, custom: dict[str, Vehicle]) -> VehicleTask:
    from proxplan.physics import resolve_vehicle

    data = _mapping(data, where, "type, start and one of goal / hover / dock")
    _unknown(data, VEHICLE_KEYS, where)
    if "type" not in data:
        raise UserError(f"{where}.type: missing; expected a vehicle type name (proxplan vehicles lists them)")
    type_name = str(data["type"])
    vehicle = resolve_vehicle(type_name, custom, where=f"{where}.type")
    if "start" not in data:
        raise UserError(f"{where}.start: missing; expected [x, y, z] in metres")
    start = _vec3(data["start"], f"{where}.start")
    modes = [k for k in ("goal", "hover", "dock") if k in data and data[k] not in (None, False)]
    if len(modes) != 1:
        raise UserError(
            f"{where}: expected exactly one of 'goal: [x, y, z]', 'hover: true' or "
            f"'dock: {{with: NAME, offset: [x, y, z]}}', got {modes or 'none'}"
        )
    goal = dock_with = dock_offset = None
    hover = False
    if modes[0] == "goal":
        goal = _vec3(data["goal"], f"{where}.goal")
    elif modes[0] == "hover":
        if data["hover"] is not True:
            raise UserError(f"{where}.hover: expected true, got {data['hover']!r}")
        hover = True
    else:
        dock = _mapping(data["dock"], f"{where}.dock", "{with: NAME, offset: [x, y, z]}")
        _unknown(dock, ("with", "offset"), f"{where}.dock")
        if "with" not in dock or "offset" not in dock:
            raise UserError(f"{where}.dock: expected {{with: NAME, offset: [x, y, z]}} (both keys)")
        dock_with = str(dock["with"])
        dock_offset = _vec3(dock["offset"], f"{where}.dock.offset")
    kin = vehicle.kinematic_limits
    speed, accel, jerk = kin.max_speed_mps, kin.max_accel_mps2, kin.max_jerk_mps3
    return VehicleTask(
        name=name,
        type_name=type_name,
        vehicle=vehicle,
        start_m=start,
        goal_m=goal,
        hover=hover,
        dock_with=dock_with,
        dock_offset_m=dock_offset,
        max_speed_mps=_positive(data.get("max_speed_mps", speed), f"{where}.max_speed_mps", upper=20.0),
        max_accel_mps2=_positive(data.get("max_accel_mps2", accel), f"{where}.max_accel_mps2", upper=30.0),
        max_jerk_mps3=_positive(data.get("max_jerk_mps3", jerk), f"{where}.max_jerk_mps3", upper=500.0),
    )


def _limits(data: Any, where: str) -> Limits:
    if data is None:
        return Limits()
    data = _mapping(data, where, ", ".join(LIMIT_KEYS))
    _unknown(data, LIMIT_KEYS, where)
    d = Limits()
    rule = data.get("invalid_zone_rule", d.invalid_zone_rule)
    if rule not in INVALID_ZONE_RULES:
        raise UserError(f"{where}.invalid_zone_rule: expected one of {', '.join(INVALID_ZONE_RULES)}, got {rule!r}")
    margin = data.get("obstacle_margin_m", d.obstacle_margin_m)
    if isinstance(margin, bool) or not isinstance(margin, (int, float)) or not (0 <= margin < 10):
        raise UserError(f"{where}.obstacle_margin_m: expected a number in [0, 10) m, got {margin!r}")
    tube = data.get("tracking_margin_m", d.tracking_margin_m)
    if isinstance(tube, bool) or not isinstance(tube, (int, float)) or not (0 <= tube < 1):
        raise UserError(f"{where}.tracking_margin_m: expected a number in [0, 1) m, got {tube!r}")
    return Limits(
        authority_fraction=_positive(
            data.get("authority_fraction", d.authority_fraction), f"{where}.authority_fraction", upper=1.0
        ),
        min_separation_m=_positive(
            data.get("min_separation_m", d.min_separation_m), f"{where}.min_separation_m", upper=10.0
        ),
        invalid_zone_rule=str(rule),
        obstacle_margin_m=float(margin),
        time_horizon_s=_positive(data.get("time_horizon_s", d.time_horizon_s), f"{where}.time_horizon_s", upper=600.0),
        tracking_margin_m=float(tube),
    )


def _check_geometry(sc: Scenario, label: str) -> None:
    lo, hi = sc.workspace_min_m, sc.workspace_max_m
    for name, task in sc.vehicles.items():
        points = [("start", task.start_m)]
        if task.goal_m is not None:
            points.append(("goal", task.goal_m))
        elif task.dock_with is not None:
            points.append(("dock (target final position + offset)", sc.final_position_m(name)))
        for key, p in points:
            where = f"{label}: vehicles.{name}.{key.split()[0]}"
            if np.any(p < lo) or np.any(p > hi):
                raise UserError(
                    f"{where}: {p.tolist()} is outside the workspace {lo.tolist()}..{hi.tolist()}; expected a point inside it"
                )
            for i, box in enumerate(sc.obstacles):
                if box.contains(p):
                    raise UserError(
                        f"{where}: {p.tolist()} is inside obstacles[{i}] {box.min_m.tolist()}..{box.max_m.tolist()}; expected free space"
                    )


def _check_docks(vehicles: dict[str, VehicleTask], label: str) -> None:
    for name, task in vehicles.items():
        if task.dock_with is None:
            continue
        where = f"{label}: vehicles.{name}.dock.with"
        if task.dock_with == name:
            raise UserError(f"{where}: a vehicle cannot dock with itself; expected another vehicle's name")
        if task.dock_with not in vehicles:
            raise UserError(f"{where}: no vehicle named {task.dock_with!r}; expected one of {', '.join(vehicles)}")
        seen = [name]
        cur: str | None = task.dock_with
        while cur is not None:
            if cur in seen:
                raise UserError(
                    f"{where}: docks form a cycle ({' -> '.join(seen + [cur])}); expected a chain ending at a vehicle with goal or hover"
                )
            seen.append(cur)
            cur = vehicles[cur].dock_with


def scenario_from_dict(
    doc: Any,
    *,
    source_path: str | Path | None = None,
    vehicle_types: Mapping[str, Vehicle] | None = None,
    label: str | None = None,
    model: CalibratedModel | None = None,
) -> Scenario:
    """Validate a parsed scenario mapping; ``source_path`` resolves ``vehicle_file`` and
    ``model_file`` and labels errors.

    ``vehicle_types`` (e.g. a plan's embedded types) are looked up before the scenario's
    ``model_file``, its ``vehicle_file`` and the built-in types; ``label`` names the source in
    errors (default: the path). ``model`` (``--model FILE``) replaces the scenario's ``model_file``.
    """
    path = Path(source_path) if source_path is not None else None
    label = label or (str(path) if path is not None else "<scenario>")
    if not isinstance(doc, Mapping):
        raise UserError(f"{label}: expected a YAML mapping with keys {', '.join(TOP_KEYS)}")
    _unknown(doc, TOP_KEYS, f"{label}: scenario")
    for key in ("workspace", "vehicles"):
        if key not in doc:
            raise UserError(f"{label}: {key}: missing; required top-level key")
    ws = _mapping(doc["workspace"], f"{label}: workspace", "{min: [x, y, z], max: [x, y, z]}")
    ws_box = _box(ws, f"{label}: workspace")
    obstacles_raw = doc.get("obstacles") or []
    if not isinstance(obstacles_raw, list):
        raise UserError(f"{label}: obstacles: expected a list of {{min: [x, y, z], max: [x, y, z]}} boxes")
    obstacles = tuple(_box(o, f"{label}: obstacles[{i}]") for i, o in enumerate(obstacles_raw))
    limits = _limits(doc.get("limits"), f"{label}: limits")
    calibrated = model if model is not None else _model_file(doc, path, label)
    field_form = calibrated.options.field_form if calibrated is not None else None
    stack_shielding = calibrated.options.stack_shielding if calibrated is not None else None
    effects: tuple[Effect, ...] = ()
    if calibrated is not None:
        from proxplan.physics import between_vehicle_effects

        effects = between_vehicle_effects(calibrated.effects)
    if "model" in doc and doc["model"] is not None:
        section = _mapping(
            doc["model"], f"{label}: model", "{field_form: inverse-z|printed, stack_shielding: 0..1, effects: [...]}"
        )
        _unknown(section, ("field_form", "stack_shielding", "effects"), f"{label}: model")
        if "stack_shielding" in section:
            eta = section["stack_shielding"]
            from proxplan.physics import MAX_STACK_SHIELDING

            if isinstance(eta, bool) or not isinstance(eta, (int, float)) or not 0.0 <= eta <= MAX_STACK_SHIELDING:
                raise UserError(
                    f"{label}: model.stack_shielding: expected a number in [0, {MAX_STACK_SHIELDING:g}] (-), got {eta!r}"
                )
            stack_shielding = float(eta)
        from proxplan.physics import FIELD_FORMS, between_vehicle_effects, effects_from_list

        field_form = section.get("field_form", field_form)
        if field_form is not None and field_form not in FIELD_FORMS:
            raise UserError(f"{label}: model.field_form: expected one of {', '.join(FIELD_FORMS)}, got {field_form!r}")
        effects += between_vehicle_effects(effects_from_list(section.get("effects"), f"{label}: model.effects"))
    model_types = dict(calibrated.vehicles) if calibrated is not None else {}
    custom = {**_vehicle_types(doc, path, label), **model_types, **dict(vehicle_types or {})}
    vraw = _mapping(doc["vehicles"], f"{label}: vehicles", "NAME: {type, start, goal|hover|dock}")
    if not vraw:
        raise UserError(f"{label}: vehicles: expected at least one vehicle")
    if len(vraw) > MAX_VEHICLES:
        raise UserError(
            f"{label}: vehicles: expected at most {MAX_VEHICLES} vehicles, got {len(vraw)} (split the swarm into groups)"
        )
    vehicles = {str(n): _task(str(n), d, f"{label}: vehicles.{n}", custom) for n, d in vraw.items()}
    _check_docks(vehicles, label)
    limits_raw = doc.get("limits")
    if not (isinstance(limits_raw, Mapping) and "tracking_margin_m" in limits_raw):
        limits = dataclasses.replace(limits, tracking_margin_m=scenario_tube_m(vehicles))
    name = doc.get("name", path.stem if path is not None else "scenario")
    if not isinstance(name, str) or not name:
        raise UserError(f"{label}: name: expected a non-empty string, got {name!r}")
    sc = Scenario(
        name=name,
        source_path=str(path.resolve()) if path is not None else None,
        workspace_min_m=ws_box.min_m,
        workspace_max_m=ws_box.max_m,
        obstacles=obstacles,
        limits=limits,
        vehicles=vehicles,
        spec=copy.deepcopy(dict(doc)),
        field_form=field_form,
        stack_shielding=stack_shielding,
        load_notes=tuple(_vehicle_file_notes(doc, path) + _model_notes(calibrated, label) + _unmapped(effects, label)),
        effects=effects,
    )
    _check_geometry(sc, label)
    return sc


def load_scenario(path: str | Path, *, model: CalibratedModel | None = None) -> Scenario:
    """Read and validate a scenario YAML file; UserError naming the file, key and expected form.
    ``model`` (a calibrated model, ``--model FILE``) replaces the scenario's ``model_file``."""
    path = Path(path)
    doc = read_yaml(path, what="scenario file")
    return scenario_from_dict(doc, source_path=path, model=model)
