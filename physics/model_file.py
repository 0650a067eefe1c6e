"""The calibrated model file: the ONE reader and writer of what ``proxplan identify --save-model``
saves and ``costmap``/``plan``/``verify``/``simulate`` apply (``--model FILE`` or ``model_file:``).

File layout (YAML)::

    format_version: 2
    vehicles:                       # the vehicle-YAML form (proxplan.physics.vehicle_yaml), calibrated
      small-quad: {base: small-quad, mass_kg: 0.034, ...}
    model:
      field_form: inverse-z         # ModelOptions (drag_coefficient, air_density_kgpm3 optional)
      drag_coefficient: 1.18
      stack_shielding: 1.0          # optional, proxplan.physics.stack (eta, -)
      air_density_kgpm3: 1.225
      effects:                      # proxplan.physics.effects names with their parameters (units in names)
        - {name: near_field, params: {amplitude: 0.4, decay_L: 3.0}}
      thrust_scales: {small-quad: 1.02}   # per vehicle type, multiplies the logged thrust, -
      uncertainty: {small-quad.c_ax: 0.3} # optional one-sigma of fitted parameters (same units)
      measurement:                  # optional: how identify measured the disturbance (proxplan.identify.evaluate
        derivative: savgol          # reads and checks it): derivative, window_s, polyorder,
        window_s: 0.15              # motor_time_constant_s, and per type the PWM*Vbat thrust map
        thrust_maps: {small-quad: {coef: [c0, c1, c2, c3], x_max_V: 3.3}}

Format 1 (no ``format_version``; what identify wrote before) is read with a note: it has no
thrust scales or uncertainties. A newer ``format_version`` is a one-line error. Every error is a
:class:`~proxplan.fileio.errors.UserError` naming the file and the key.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from proxplan.fileio import UserError, atomic_write_text, read_yaml
from proxplan.physics.builtin_vehicles import BUILTIN_VEHICLES
from proxplan.physics.disturbance import DEFAULT_OPTIONS, ModelOptions
from proxplan.physics.effects import DISCOVERED_PREFIX, EFFECT_NAMES, PARAMETERS, TARGET_ONLY_EFFECTS, Effect
from proxplan.physics.features import between_vehicle_part, parse_term_key
from proxplan.physics.stack import MAX_STACK_SHIELDING
from proxplan.physics.vehicle_yaml import vehicle_from_dict, vehicle_to_yaml_dict
from proxplan.physics.vehicles import Vehicle
from proxplan.physics.velocity_field import FIELD_FORMS

MODEL_FORMAT_VERSION = 2
"""Version written; 1 = the older identify output without ``format_version`` (read with a note)."""

TOP_KEYS = ("format_version", "vehicles", "model")
MODEL_KEYS = (
    "field_form", "drag_coefficient", "air_density_kgpm3", "stack_shielding", "effects", "thrust_scales", "uncertainty", "measurement",
)  # fmt: skip
HEADER = (
    "# written by proxplan identify: calibrated vehicles, model options and kept effects.\n"
    "# Use with: proxplan costmap|plan|simulate --model THIS_FILE ..., or 'model_file: THIS_FILE' in a scenario.\n"
)


@dataclass(frozen=True)
class CalibratedModel:
    """A saved calibrated model.

    ``vehicles``: calibrated vehicle types by name (they override built-in types of the same name);
    ``options``: disturbance-model options; ``effects``: effects beyond the base model with their
    parameters (:mod:`proxplan.physics.effects`); ``thrust_scales``: per vehicle type, dimensionless factor
    on the logged motor thrust (identification only); ``uncertainty``: optional one-sigma of fitted
    parameters, ``{"TYPE.param" or "effect.param": std}`` in the parameter's units;
    ``notes``: what the reader should know about how the file was read (not saved).
    """

    vehicles: Mapping[str, Vehicle] = field(default_factory=dict)
    options: ModelOptions = DEFAULT_OPTIONS
    effects: tuple[Effect, ...] = ()
    thrust_scales: Mapping[str, float] = field(default_factory=dict)
    uncertainty: Mapping[str, float] = field(default_factory=dict)
    measurement: Mapping[str, Any] = field(default_factory=dict)  # identify's measurement settings (plain data)
    format_version: int = MODEL_FORMAT_VERSION
    notes: tuple[str, ...] = field(default=(), compare=False)

    @property
    def between_vehicle_effects(self) -> tuple[Effect, ...]:
        """The effects that act between vehicles (what cost maps, planner and verifier apply)."""
        return between_vehicle_effects(self.effects)


def between_vehicle_effects(effects: Iterable[Effect]) -> tuple[Effect, ...]:
    """``effects`` without the target-only ones (:data:`proxplan.physics.effects.TARGET_ONLY_EFFECTS`):
    the effects that, like the base model, are a sum over sources. A discovered term keeps only its
    pairwise features (:data:`proxplan.physics.features.TARGET_ONLY_FEATURES` dropped)."""
    out = []
    for e in effects:
        if e.name.startswith(DISCOVERED_PREFIX):
            part = between_vehicle_part(dict(e.params))
            if part:
                out.append(Effect(e.name, part))
        elif e.name not in TARGET_ONLY_EFFECTS:
            out.append(e)
    return tuple(out)


def effects_to_list(effects: Sequence[Effect]) -> list[dict[str, Any]]:
    """The YAML/JSON list form ``[{name, params: {...}}]`` of ``effects`` (every parameter written)."""
    return [{"name": e.name, "params": {k: float(v) for k, v in e.full_params().items()}} for e in effects]


def effects_from_list(raw: Any, where: str) -> tuple[Effect, ...]:
    """Parse ``[{name, params}]`` into effects; UserError naming ``where`` (``FILE: KEY``) otherwise."""
    if raw is None:
        return ()
    if not isinstance(raw, list):
        raise UserError(f"{where}: expected a list of {{name: EFFECT, params: {{...}}}}")
    out = []
    for i, item in enumerate(raw):
        w = f"{where}[{i}]"
        if not isinstance(item, Mapping) or "name" not in item:
            raise UserError(f"{w}: expected a mapping {{name: EFFECT, params: {{...}}}}")
        unknown = sorted(set(item) - {"name", "params"})
        if unknown:
            raise UserError(f"{w}: unknown key {unknown[0]!r}; expected name and params")
        name = item["name"]
        if isinstance(name, str) and name.startswith(DISCOVERED_PREFIX):  # proxplan.identify.discovery term
            out.append(Effect(name, _discovered_params(item.get("params"), w)))
            continue
        if name not in PARAMETERS:
            raise UserError(f"{w}.name: unknown effect {name!r}; known effects: {', '.join(EFFECT_NAMES)}")
        params = item.get("params") or {}
        if not isinstance(params, Mapping):
            raise UserError(f"{w}.params: expected a mapping PARAM: number")
        values = {}
        for key, value in params.items():
            if key not in PARAMETERS[name]:
                raise UserError(
                    f"{w}.params.{key}: unknown parameter of {name}; expected {', '.join(PARAMETERS[name])}"
                )
            values[str(key)] = _finite(value, f"{w}.params.{key}")
        out.append(Effect(str(name), values))
    return tuple(out)


def _discovered_params(raw: Any, where: str) -> dict[str, float]:
    if not isinstance(raw, Mapping):
        raise UserError(f"{where}.params: expected a mapping '<channel>*<feature>': number")
    for key in raw:
        try:
            parse_term_key(str(key))
        except ValueError as exc:
            raise UserError(f"{where}.params: {exc}") from None
    return {str(k): _finite(v, f"{where}.params.{k}") for k, v in raw.items()}


def _finite(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(float(value)):
        raise UserError(f"{where}: expected a finite number, got {value!r}")
    return float(value)


def _number_map(raw: Any, where: str, *, positive: bool) -> dict[str, float]:
    if raw is None:
        return {}
    if not isinstance(raw, Mapping):
        raise UserError(f"{where}: expected a mapping NAME: number")
    out = {}
    for key, value in raw.items():
        v = _finite(value, f"{where}.{key}")
        if positive and v <= 0.0:
            raise UserError(f"{where}.{key}: expected a positive number, got {value!r}")
        out[str(key)] = v
    return out


def _mapping(raw: Any, where: str) -> dict[str, Any]:
    if raw is None:
        return {}
    if not isinstance(raw, Mapping):
        raise UserError(f"{where}: expected a mapping")
    return dict(raw)


def options_from_mapping(model: Mapping, where: str) -> ModelOptions:
    """ModelOptions from a ``model:`` mapping (field_form, drag_coefficient, air_density_kgpm3,
    stack_shielding)."""
    form = model.get("field_form", DEFAULT_OPTIONS.field_form)
    if form not in FIELD_FORMS:
        raise UserError(f"{where}.field_form: expected one of {', '.join(FIELD_FORMS)}, got {form!r}")
    values: dict[str, Any] = {"field_form": form}
    for key in ("drag_coefficient", "air_density_kgpm3"):
        if key in model:
            values[key] = _finite(model[key], f"{where}.{key}")
            if values[key] <= 0.0:
                raise UserError(f"{where}.{key}: expected a positive number, got {model[key]!r}")
    if "stack_shielding" in model:
        values["stack_shielding"] = _finite(model["stack_shielding"], f"{where}.stack_shielding")
        if not 0.0 <= values["stack_shielding"] <= MAX_STACK_SHIELDING:
            raise UserError(
                f"{where}.stack_shielding: expected a number in [0, {MAX_STACK_SHIELDING:g}] (-), got {model['stack_shielding']!r}"
            )
    return ModelOptions(**values)


def model_from_dict(doc: Any, *, label: str = "<model>") -> CalibratedModel:
    """Validate a parsed model-file mapping (``label`` names the file in errors)."""
    if not isinstance(doc, Mapping) or not isinstance(doc.get("vehicles"), Mapping):
        raise UserError(f"{label}: expected a top-level 'vehicles:' mapping of NAME: parameters (a model file)")
    unknown = sorted(set(doc) - set(TOP_KEYS))
    if unknown:
        raise UserError(f"{label}: unknown top-level key {unknown[0]!r}; expected {', '.join(TOP_KEYS)}")
    notes: list[str] = []
    if "format_version" not in doc:
        version = 1
        notes.append(
            f"{label}: format_version: missing, read as model format 1 (an older identify output: no thrust "
            "scales or uncertainties); re-run identify --save-model for the current format"
        )
    else:
        version = doc["format_version"]
        if isinstance(version, bool) or not isinstance(version, int) or not 1 <= version <= MODEL_FORMAT_VERSION:
            raise UserError(
                f"{label}: format_version: {version!r} is not a model format this proxplan reads; expected 1.."
                f"{MODEL_FORMAT_VERSION} (update proxplan or re-run identify --save-model)"
            )
    vehicles = {str(n): vehicle_from_dict(str(n), d, source=label) for n, d in doc["vehicles"].items()}
    model = doc.get("model") or {}
    if not isinstance(model, Mapping):
        raise UserError(f"{label}: model: expected a mapping ({', '.join(MODEL_KEYS)})")
    bad = sorted(set(model) - set(MODEL_KEYS))
    if bad:
        raise UserError(f"{label}: model: unknown key {bad[0]!r}; expected one of {', '.join(MODEL_KEYS)}")
    return CalibratedModel(
        vehicles=vehicles,
        options=options_from_mapping(model, f"{label}: model"),
        effects=effects_from_list(model.get("effects"), f"{label}: model.effects"),
        thrust_scales=_number_map(model.get("thrust_scales"), f"{label}: model.thrust_scales", positive=True),
        uncertainty=_number_map(model.get("uncertainty"), f"{label}: model.uncertainty", positive=False),
        measurement=_mapping(model.get("measurement"), f"{label}: model.measurement"),
        format_version=int(version),
        notes=tuple(notes),
    )


def load_model_file(path: str | Path) -> CalibratedModel:
    """Read and validate a model file; UserError naming the file and key on any problem."""
    path = Path(path)
    return model_from_dict(read_yaml(path, what="model file"), label=str(path))


def model_file_dict(model: CalibratedModel) -> dict[str, Any]:
    """The model-file mapping of ``model`` (current format; built-in names recorded as ``base``)."""
    opts = model.options
    body: dict[str, Any] = {
        "field_form": opts.field_form,
        "drag_coefficient": float(opts.drag_coefficient),
        "air_density_kgpm3": float(opts.air_density_kgpm3),
        "stack_shielding": float(opts.stack_shielding),
        "effects": effects_to_list(model.effects),
        "thrust_scales": {k: float(v) for k, v in model.thrust_scales.items()},
    }
    if model.uncertainty:
        body["uncertainty"] = {k: float(v) for k, v in model.uncertainty.items()}
    if model.measurement:
        body["measurement"] = dict(model.measurement)
    return {
        "format_version": MODEL_FORMAT_VERSION,
        "vehicles": {
            name: vehicle_to_yaml_dict(v, base=name if name in BUILTIN_VEHICLES else None)
            for name, v in model.vehicles.items()
        },
        "model": body,
    }


def write_model_file(model: CalibratedModel, path: str | Path) -> Path:
    """Write ``model`` to ``path`` atomically (YAML with a usage header); returns the path."""
    import yaml

    return atomic_write_text(Path(path), HEADER + yaml.safe_dump(model_file_dict(model), sort_keys=False))


def load_model_section(path: str | Path) -> dict[str, Any]:
    """The ``model:`` mapping of a model file in the current form (effects with every parameter)."""
    return dict(model_file_dict(load_model_file(path))["model"])


def target_only_notes(model: CalibratedModel, label: str) -> list[str]:
    """Notes for the effects of ``model`` that planning does not apply: the target-only ones
    (thrust_bias, ground_effect, own_velocity: the vehicle's own thrust error, which its controller
    meets whatever the plan); the effects between vehicles are applied."""
    names = [e.name for e in model.effects if e.name in TARGET_ONLY_EFFECTS]
    if not names:
        return []
    return [
        f"{label}: model.effects: {', '.join(names)} act on a vehicle alone and are not applied by cost maps and "
        "planning (the effects between vehicles are)"
    ]


def vehicle_file_notes(path: str | Path) -> list[str]:
    """Notes for a ``vehicle_file`` that is a model file: only its vehicles are used there."""
    doc = read_yaml(path, what="vehicle file")
    model = doc.get("model") if isinstance(doc, Mapping) else None
    if not isinstance(model, Mapping) or not model.get("effects"):
        return []
    return [
        f"{path}: model.effects are not applied through vehicle_file (vehicles only); give the file as "
        "'model_file:' in the scenario or --model to apply them"
    ]
