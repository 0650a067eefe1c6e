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
      residual_spread:              # optional: the F_z spread the model cannot predict
        form: jet-shear-1           # (proxplan.physics.residual_spread), and its 90 % interval
        quantile_90: 1.7
        quantile_90_overhead: [1.6, 1.7, 2.1]
        by_type: {small-quad: {floor_N: 0.01, force_share: 0.3, shear: 0.02, stack: 0.2, limit: 0.05, ground: 0.1,
                               flight_N: 0.012}}   # flight_N optional (absent: 0, a file saved before stop 71)

Format 1 (no ``format_version``; what identify wrote before) is read with a note: it has no
thrust scales or uncertainties. A newer ``format_version`` is a one-line error. Every error is a
:class:`~proxplan.fileio.errors.UserError` naming the file and the key.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any

from pydantic import Field, TypeAdapter, field_validator, model_validator

from proxplan.fileio import (
    FileModel,
    Name,
    Number,
    Positive,
    Text,
    Vec3,
    Whole,
    atomic_write_text,
    optional,
    problem,
    read_yaml,
    validate,
)
from proxplan.physics.builtin_vehicles import BUILTIN_VEHICLES
from proxplan.physics.disturbance import DEFAULT_OPTIONS, ModelOptions
from proxplan.physics.effects import (
    DISCOVERED_PREFIX,
    EFFECT_NAMES,
    LAG_BOUNDS_S,
    LAG_PARAM,
    PARAMETERS,
    TARGET_ONLY_EFFECTS,
    Effect,
)
from proxplan.physics.feature_terms import between_vehicle_part, parse_term_key
from proxplan.physics.residual_spread import SPREAD_FORM, ResidualSpread, TypeSpread
from proxplan.physics.stack import MAX_STACK_SHIELDING
from proxplan.physics.vehicle_yaml import VehicleEntry, build_vehicles, vehicle_to_yaml_dict
from proxplan.physics.vehicles import Vehicle
from proxplan.physics.velocity_field import FieldForm

MODEL_FORMAT_VERSION = 2
"""Version written; 1 = the older identify output without ``format_version`` (read with a note)."""

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
    residual_spread: ResidualSpread | None = None  # what the model cannot predict (proxplan.physics.residual_spread)
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


# ---------------------------------------------------------------------------- declared effect lists


def _effect_variants(schema: dict[str, Any]) -> None:
    """JSON Schema: one variant per library effect (its parameters, with default and fit bounds), and
    the discovered terms (``discovered:...``, parameters ``<channel>*<feature>``)."""
    variants: list[dict[str, Any]] = []
    for name in EFFECT_NAMES:
        params = {
            key: {"type": "number", "description": f"default {d:g}; fit bounds [{lo:g}, {hi:g}]; unit in the name"}
            for key, (d, lo, hi) in PARAMETERS[name].items()
        } | {
            LAG_PARAM: {
                "type": "number",
                "minimum": LAG_BOUNDS_S[0],
                "maximum": LAG_BOUNDS_S[1],
                "description": "delay of the effect behind its cause, s (default 0)",
            }
        }
        variants.append({
            "properties": {"name": {"const": name},
                           "params": {"type": "object", "properties": params, "additionalProperties": False}},
            "required": ["name"],
        })  # fmt: skip
    variants.append({
        "properties": {"name": {"type": "string", "pattern": f"^{DISCOVERED_PREFIX}"},
                       "params": {"type": "object", "additionalProperties": {"type": "number"},
                                  "description": "coefficients named '<channel>*<feature>' or '<channel>*W*<feature>', "
                                                 "either optionally ending in '@<vehicle type>' (acting on that "
                                                 "type only; proxplan.physics.feature_terms)"}},
        "required": ["name", "params"],
    })  # fmt: skip
    schema["oneOf"] = variants


class EffectEntry(FileModel, json_schema_extra=_effect_variants):
    """One effect beyond the base model: a library effect (``proxplan.physics.effects``) or a term found
    by ``proxplan identify`` (``discovered:...``), with its parameters."""

    name: Text = Field(description=f"effect name: one of {', '.join(EFFECT_NAMES)}, or discovered:LABEL")
    params: dict[Text, Number] = optional(
        "parameter values (units in the names); parameters left out take their defaults"
    )

    @field_validator("name")
    @classmethod
    def _known(cls, name: str) -> str:
        if not name.startswith(DISCOVERED_PREFIX) and name not in PARAMETERS:
            raise problem(f"unknown effect {name!r}; known effects: {', '.join(EFFECT_NAMES)}")
        return name

    @model_validator(mode="after")
    def _parameters_of_the_effect(self) -> EffectEntry:
        params = self.params or {}
        if self.name.startswith(DISCOVERED_PREFIX):
            if self.params is None:
                raise problem("expected a mapping '<channel>*<feature>': number", at="params")
            for key in params:
                try:
                    parse_term_key(key)
                except ValueError as exc:
                    raise problem(str(exc), at="params") from None
            return self
        for key in params:
            if key not in PARAMETERS[self.name] and key != LAG_PARAM:
                raise problem(
                    f"unknown parameter of {self.name}; expected {', '.join(PARAMETERS[self.name])} or {LAG_PARAM}",
                    at=f"params.{key}",
                )
        lag = float(params.get(LAG_PARAM, 0.0))
        if not LAG_BOUNDS_S[0] <= lag <= LAG_BOUNDS_S[1]:
            raise problem(f"expected a delay in [{LAG_BOUNDS_S[0]:g}, {LAG_BOUNDS_S[1]:g}] s", at=f"params.{LAG_PARAM}")
        return self

    def effect(self) -> Effect:
        return Effect(self.name, {k: float(v) for k, v in (self.params or {}).items()})


EffectList = list[EffectEntry]
_EFFECT_LIST: TypeAdapter[list[EffectEntry] | None] = TypeAdapter(EffectList | None)


def effects_to_list(effects: Sequence[Effect]) -> list[dict[str, Any]]:
    """The YAML/JSON list form ``[{name, params: {...}}]`` of ``effects`` (every parameter written)."""
    return [{"name": e.name, "params": {k: float(v) for k, v in e.full_params().items()}} for e in effects]


def effects_from_entries(entries: Sequence[EffectEntry] | None) -> tuple[Effect, ...]:
    """The effects of a validated effect list."""
    return tuple(e.effect() for e in entries or ())


def effects_from_list(raw: Any, where: str) -> tuple[Effect, ...]:
    """Parse ``[{name, params}]`` into effects; UserError naming ``where`` (``FILE: KEY``) otherwise."""
    return effects_from_entries(validate(_EFFECT_LIST, raw, label=where))


# ------------------------------------------------------------------------------- declared model file


class ModelOptionsPart(FileModel):
    """Disturbance-model options and effects (a scenario's ``model:`` section; a model file's adds more)."""

    field_form: FieldForm = optional("form of (S0-1): inverse-z (1/z decay, default) or printed (1/sqrt(z))")
    stack_shielding: Annotated[Number, Field(ge=0, le=MAX_STACK_SHIELDING)] = optional(
        "eta of proxplan.physics.stack: how much an upper source shields the jet of one below, -"
    )
    effects: EffectList = optional("effects beyond the base model, [{name, params}]")


class TypeSpreadEntry(FileModel):
    """The residual spread of one vehicle type (proxplan.physics.residual_spread)."""

    floor_N: Annotated[Number, Field(ge=0)] = Field(description="spread of F_z away from every jet, N")
    force_share: Annotated[Number, Field(ge=0)] = optional("spread per unit of each source's mean push, -")
    shear: Annotated[Number, Field(ge=0)] = optional("spread in a jet's shear layer per unit of weight, -")
    stack: Annotated[Number, Field(ge=0)] = optional("spread per unit of the cross terms of merged jets' pushes, -")
    limit: Annotated[Number, Field(ge=0)] = optional(
        "spread with a motor at its floor or ceiling, per unit of weight, -"
    )
    ground: Annotated[Number, Field(ge=0)] = optional("spread in the ground's recirculation per unit of weight, -")
    flight_N: Annotated[Number, Field(ge=0)] = optional(
        "spread between vehicle logs of the constant part of the residual (one per log), N (absent: 0)"
    )


class ResidualSpreadPart(FileModel):
    """What the model cannot predict: the spread of F_z by place in the jet (``proxplan identify``)."""

    form: Text = optional(f"the form of the spread model: {SPREAD_FORM}")
    quantile_90: Positive = optional("the 90 % interval is |residual| <= quantile_90 sigma, -")
    quantile_90_overhead: list[Positive] = optional(
        "the quantile by the number of sources overhead (0, 1, 2 or more), -"
    )
    by_type: dict[Name, TypeSpreadEntry] = Field(description="per vehicle type, its spread parameters")

    @field_validator("form")
    @classmethod
    def _known_form(cls, form: str) -> str:
        if form != SPREAD_FORM:
            raise problem(f"unknown spread form {form!r}; expected {SPREAD_FORM}")
        return form

    def spread(self) -> ResidualSpread:
        return ResidualSpread(
            by_type={t: TypeSpread(float(e.floor_N), float(e.force_share or 0.0), float(e.shear or 0.0),
                                   float(e.stack or 0.0), float(e.limit or 0.0), float(e.ground or 0.0),
                                   float(e.flight_N or 0.0))
                     for t, e in self.by_type.items()},
            quantile_90=float(self.quantile_90) if self.quantile_90 is not None else ResidualSpread().quantile_90,
            quantile_90_overhead=tuple(float(q) for q in self.quantile_90_overhead or ()),
        )  # fmt: skip


class ModelSection(ModelOptionsPart):
    """The ``model:`` section of a model file."""

    drag_coefficient: Positive = optional("flat-plate drag coefficient C_D of (S0-3), - (default 1.18)")
    air_density_kgpm3: Positive = optional("air density, kg/m^3 (default 1.225)")
    thrust_scales: dict[Name, Positive] = optional(
        "per vehicle type, factor on the logged motor thrust, - (identification only)"
    )
    uncertainty: dict[Name, Number] = optional(
        "one-sigma of fitted parameters, 'TYPE.param' or 'effect.param': std in the parameter's unit"
    )
    measurement: dict[Text, Any] = optional("how identify measured the disturbance (checked by proxplan evaluate)")
    residual_spread: ResidualSpreadPart = optional("the spread of F_z the model cannot predict, by place in the jet")


class ModelFile(FileModel):
    """A calibrated model file (``proxplan identify --save-model``; ``--model FILE`` or ``model_file:``)."""

    format_version: Whole = optional(
        f"model-file format, 1..{MODEL_FORMAT_VERSION} (absent: 1, the older identify output)",
        json_schema_extra={"minimum": 1, "maximum": MODEL_FORMAT_VERSION},
    )
    vehicles: dict[Name, VehicleEntry] = Field(description="calibrated vehicle types (the vehicle-file form)")
    model: ModelSection = optional("model options, effects, thrust scales and uncertainties")

    @field_validator("format_version")
    @classmethod
    def _readable(cls, version: int) -> int:
        if not 1 <= version <= MODEL_FORMAT_VERSION:
            raise problem(
                f"{version!r} is not a model format this proxplan reads; expected 1..{MODEL_FORMAT_VERSION} "
                "(update proxplan or re-run identify --save-model)"
            )
        return version


class TruthFile(FileModel):
    """A truth file of ``proxplan simulate --truth``: the simulated world beyond the planner's model
    (read by ``proxplan.flightsim.truth``)."""

    field_form: FieldForm = optional("form of (S0-1) in the simulated world (default inverse-z)")
    wind_mps: Vec3 = optional("steady wind [wx, wy, wz], world frame, m/s")
    effects: EffectList = optional("effects of the simulated world, [{name, params}]")


def options_from_section(section: ModelOptionsPart | None) -> ModelOptions:
    """ModelOptions of a validated ``model:`` section (defaults for what it leaves out)."""
    keys = {f.name for f in dataclasses.fields(ModelOptions)}
    given = section.model_dump(exclude_unset=True) if section is not None else {}
    return ModelOptions(**{k: v for k, v in given.items() if k in keys})


def model_from_dict(doc: Any, *, label: str = "<model>") -> CalibratedModel:
    """Validate a parsed model-file mapping (``label`` names the file in errors)."""
    model_file = validate(ModelFile, doc, label=label)
    notes: list[str] = []
    version = model_file.format_version
    if version is None:
        version = 1
        notes.append(
            f"{label}: format_version: missing, read as model format 1 (an older identify output: no thrust "
            "scales or uncertainties); re-run identify --save-model for the current format"
        )
    section = model_file.model or ModelSection()
    return CalibratedModel(
        vehicles=build_vehicles(model_file.vehicles, source=label),
        options=options_from_section(section),
        effects=effects_from_entries(section.effects),
        thrust_scales=dict(section.thrust_scales or {}),
        uncertainty=dict(section.uncertainty or {}),
        measurement=dict(section.measurement or {}),
        residual_spread=section.residual_spread.spread() if section.residual_spread is not None else None,
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
    if model.residual_spread is not None:
        body["residual_spread"] = model.residual_spread.to_dict()
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
