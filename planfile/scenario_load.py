"""Reading a scenario file into a :class:`~proxplan.planfile.scenario.Scenario`.

The document is validated once against the declared format (:class:`ScenarioFile`); what follows
needs other files or the whole scenario: the vehicle and model files it names (relative to the
scenario), vehicle types, dock partners and chains, and every start, goal and dock point inside the
workspace and outside the obstacles. Every mistake raises :class:`proxplan.fileio.errors.UserError`
with ``FILE: KEY: what was expected``.
"""

from __future__ import annotations

import copy
import dataclasses
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from proxplan.fileio import UserError, read_yaml, validate
from proxplan.physics import CalibratedModel, Effect, Vehicle
from proxplan.planfile.scenario import Box, Limits, Scenario, VehicleTask, scenario_tube_m
from proxplan.planfile.scenario_model import BoxPart, LimitsPart, ScenarioFile, TaskPart


def _relative_file(value: str | None, key: str, path: Path | None, label: str) -> Path | None:
    """The file named by ``key`` (relative to the scenario file), checked to exist; None if absent."""
    if value is None:
        return None
    base = path.parent if path is not None else Path.cwd()
    file = (base / value).resolve()
    if not file.exists():
        raise UserError(f"{label}: {key}: file {file} does not exist (paths are relative to the scenario file)")
    return file


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


def _box(part: BoxPart) -> Box:
    return Box(min_m=np.array(part.min, dtype=float), max_m=np.array(part.max, dtype=float), name=part.name or "")


def _task(name: str, part: TaskPart, where: str, custom: Mapping[str, Vehicle]) -> VehicleTask:
    from proxplan.physics import resolve_vehicle

    vehicle = resolve_vehicle(part.type, custom, where=f"{where}.type")
    kin = vehicle.kinematic_limits
    task = part.tasks[0]
    return VehicleTask(
        name=name,
        type_name=part.type,
        vehicle=vehicle,
        start_m=np.array(part.start, dtype=float),
        goal_m=np.array(part.goal, dtype=float) if task == "goal" and part.goal is not None else None,
        hover=task == "hover",
        dock_with=part.dock.with_ if task == "dock" and part.dock is not None else None,
        dock_offset_m=np.array(part.dock.offset, dtype=float) if task == "dock" and part.dock is not None else None,
        max_speed_mps=kin.max_speed_mps if part.max_speed_mps is None else part.max_speed_mps,
        max_accel_mps2=kin.max_accel_mps2 if part.max_accel_mps2 is None else part.max_accel_mps2,
        max_jerk_mps3=kin.max_jerk_mps3 if part.max_jerk_mps3 is None else part.max_jerk_mps3,
    )


def _limits(part: LimitsPart | None, vehicles: Mapping[str, VehicleTask]) -> Limits:
    """The limits given, defaults for the rest; the tube defaults to the vehicles' largest."""
    given = part.model_dump(exclude_unset=True) if part is not None else {}
    given.setdefault("tracking_margin_m", scenario_tube_m(vehicles))
    return dataclasses.replace(Limits(), **given)


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
    from proxplan.physics import between_vehicle_effects, effects_from_entries, load_model_file, load_vehicle_file

    path = Path(source_path) if source_path is not None else None
    label = label or (str(path) if path is not None else "<scenario>")
    sf = validate(ScenarioFile, doc, label=label)
    mfile = _relative_file(sf.model_file, "model_file", path, label)
    calibrated = model if model is not None else (load_model_file(mfile) if mfile is not None else None)
    field_form = calibrated.options.field_form if calibrated is not None else None
    stack_shielding = calibrated.options.stack_shielding if calibrated is not None else None
    effects = between_vehicle_effects(calibrated.effects) if calibrated is not None else ()
    if sf.model is not None:
        field_form = sf.model.field_form or field_form
        stack_shielding = sf.model.stack_shielding if sf.model.stack_shielding is not None else stack_shielding
        effects += between_vehicle_effects(effects_from_entries(sf.model.effects))
    vfile = _relative_file(sf.vehicle_file, "vehicle_file", path, label)
    custom = {
        **(load_vehicle_file(vfile) if vfile is not None else {}),
        **(dict(calibrated.vehicles) if calibrated is not None else {}),
        **dict(vehicle_types or {}),
    }
    vehicles = {n: _task(n, part, f"{label}: vehicles.{n}", custom) for n, part in sf.vehicles.items()}
    _check_docks(vehicles, label)
    notes = _vehicle_file_notes(vfile) + _model_notes(calibrated, label) + _unmapped(effects, label)
    workspace = _box(sf.workspace)
    sc = Scenario(
        name=sf.name or (path.stem if path is not None else "scenario"),
        source_path=str(path.resolve()) if path is not None else None,
        workspace_min_m=workspace.min_m,
        workspace_max_m=workspace.max_m,
        obstacles=tuple(_box(o) for o in sf.obstacles or ()),
        limits=_limits(sf.limits, vehicles),
        vehicles=vehicles,
        spec=copy.deepcopy(dict(doc)),
        field_form=field_form,
        stack_shielding=stack_shielding,
        assign_goals=sf.assign_goals,
        load_notes=tuple(notes),
        effects=effects,
    )
    _check_geometry(sc, label)
    return sc


def _vehicle_file_notes(vfile: Path | None) -> list[str]:
    if vfile is None:
        return []
    from proxplan.physics import vehicle_file_notes

    return vehicle_file_notes(vfile)


def load_scenario(path: str | Path, *, model: CalibratedModel | None = None) -> Scenario:
    """Read and validate a scenario YAML file; UserError naming the file, key and expected form.
    ``model`` (a calibrated model, ``--model FILE``) replaces the scenario's ``model_file``."""
    path = Path(path)
    doc = read_yaml(path, what="scenario file")
    return scenario_from_dict(doc, source_path=path, model=model)
