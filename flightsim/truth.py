"""The simulator's "truth": effects beyond the planner's model, from a YAML file, and the default
world of a plan (:func:`plan_truth`: the model it was planned with, incl. a calibrated model's effects
between vehicles; a truth file adds to it, an effect of the same name replacing the plan's).

Format (every key optional)::

    field_form: inverse-z          # form of (S0-1) used by the simulated world: inverse-z | printed
    wind_mps: [1.0, 0.0, 0.0]      # steady wind, world frame, m/s: rotor drag in RotorPy's model,
                                   # and the default wind of a wake_advection effect
    effects:                       # names and parameters: proxplan.physics.effects.PARAMETERS
      - name: ground_effect
        params: {gain_k: 1.0}
      - name: near_field
        params: {amplitude: 0.5, decay_L: 3.0}

Unknown keys, names or parameters, and non-finite numbers are user errors naming file and key.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from proxplan.fileio import UserError

TOP_KEYS = ("field_form", "wind_mps", "effects")


@dataclass(frozen=True)
class TruthSpec:
    """Truth for one simulation: extra effects, steady wind (3,) m/s world frame, field form."""

    effects: tuple = ()  # tuple[proxplan.physics.effects.Effect, ...]
    wind_mps: tuple[float, float, float] = (0.0, 0.0, 0.0)
    field_form: str = "inverse-z"

    def to_dict(self) -> dict:
        from proxplan.physics import effects_to_list

        return {
            "field_form": self.field_form,
            "wind_mps": list(self.wind_mps),
            "effects": effects_to_list(self.effects),
        }


def truth_from_dict(doc: Any, *, source: str = "<truth>") -> TruthSpec:
    """Validate a truth mapping (see module docstring) into a :class:`TruthSpec`."""
    from proxplan.physics import FIELD_FORMS, Effect, effects_from_list

    if doc is None:
        doc = {}
    if not isinstance(doc, dict):
        raise UserError(f"{source}: expected a mapping with keys {', '.join(TOP_KEYS)}")
    unknown = sorted(set(doc) - set(TOP_KEYS))
    if unknown:
        raise UserError(f"{source}: unknown key {unknown[0]!r}; expected {', '.join(TOP_KEYS)}")
    form = doc.get("field_form", "inverse-z")
    if form not in FIELD_FORMS:
        raise UserError(f"{source}: field_form: expected one of {', '.join(FIELD_FORMS)}, got {form!r}")
    wind = doc.get("wind_mps", [0.0, 0.0, 0.0])
    try:
        wind_arr = np.asarray(wind, dtype=float)
    except (TypeError, ValueError):
        wind_arr = np.zeros(0)
    if wind_arr.shape != (3,) or not np.all(np.isfinite(wind_arr)):
        raise UserError(f"{source}: wind_mps: expected [wx, wy, wz] in m/s, got {wind!r}")
    effects = []
    for effect in effects_from_list(doc.get("effects"), f"{source}: effects"):
        if effect.name == "wake_advection":  # the wind of the truth file is the wake's default wind
            params = {"wind_x_mps": float(wind_arr[0]), "wind_y_mps": float(wind_arr[1]), **effect.params}
            effect = Effect(effect.name, params)
        effects.append(effect)
    return TruthSpec(tuple(effects), (float(wind_arr[0]), float(wind_arr[1]), float(wind_arr[2])), form)


def load_truth_file(path: str | Path) -> TruthSpec:
    """Read a truth YAML file; UserError on any problem."""
    from proxplan.fileio import read_yaml

    path = Path(path)
    doc = read_yaml(path, what="truth file")
    return truth_from_dict(doc, source=str(path))


def model_truth(effects: tuple = (), field_form: str | None = None) -> TruthSpec:
    """The world of a model: its effects (``proxplan.physics.Effect``) and field form (default inverse-z)."""
    return TruthSpec(effects=tuple(effects), field_form=field_form or "inverse-z")


def plan_truth(plan: Any) -> TruthSpec:
    """The default world of a plan: the model it was planned with, i.e. its field form and the
    calibrated model's effects between vehicles it carries (``scenario_spec.model``)."""
    model = (plan.scenario_spec or {}).get("model") or {}
    return model_truth(plan.effects, model.get("field_form"))


def merge_truth(base: TruthSpec, extra: TruthSpec | None, *, extra_form: bool = True) -> TruthSpec:
    """``base`` plus the effects of ``extra`` (an effect of ``extra`` replaces one of the same name
    in ``base``); wind and (with ``extra_form``) field form from ``extra``."""
    if extra is None:
        return base
    names = {e.name for e in extra.effects}
    effects = tuple(e for e in base.effects if e.name not in names) + tuple(extra.effects)
    return TruthSpec(effects, extra.wind_mps, extra.field_form if extra_form else base.field_form)
