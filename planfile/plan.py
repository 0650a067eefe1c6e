"""Plan results and the plan.json file (DESIGN.md section 4), written atomically.

plan.json keys (contract): ``scenario`` (name), ``dt_s``, ``vehicles: {NAME: {type, t_s, position_m,
velocity_mps, acceleration_mps2}}`` on one common time grid, ``metrics: {planning_time_s,
max_authority_usage, min_separation_m, makespan_s, ...}``. Extra keys: ``format_version``,
``method``, ``notes``, ``scenario_file`` (absolute path of the scenario YAML, or null) and
``scenario_spec`` (the parsed scenario mapping) so ``proxplan verify`` can re-check a plan alone.
Positions are world frame (z up), m; velocities m/s; accelerations m/s^2; times s.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from fileio.errors import UserError
from fileio.files import atomic_write_text, read_json

PLAN_FORMAT_VERSION = 1
PLAN_FILENAME = "plan.json"


@dataclass
class VehicleTrajectory:
    """One vehicle's trajectory sampled at ``t_s`` (N,), s: ``position_m``, ``velocity_mps`` and
    ``acceleration_mps2`` are (N, 3), world frame."""

    name: str
    type_name: str
    t_s: np.ndarray
    position_m: np.ndarray
    velocity_mps: np.ndarray
    acceleration_mps2: np.ndarray

    def state_at(self, t_s: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Linearly interpolated (position_m, velocity_mps, acceleration_mps2), each (M, 3);
        held at the last sample after the end (the vehicle hovers there)."""
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        out = []
        for arr in (self.position_m, self.velocity_mps, self.acceleration_mps2):
            out.append(np.column_stack([np.interp(t, self.t_s, arr[:, k]) for k in range(3)]))
        return out[0], out[1], out[2]


@dataclass
class PlanResult:
    """A multi-vehicle plan: every trajectory on one common time grid of step ``dt_s``, s."""

    scenario: str
    dt_s: float
    vehicles: dict[str, VehicleTrajectory]
    metrics: dict[str, Any] = field(default_factory=dict)
    method: str = "sampling"
    notes: list[str] = field(default_factory=list)
    scenario_file: str | None = None
    scenario_spec: dict | None = None

    @property
    def t_s(self) -> np.ndarray:
        """The common time grid (N,), s."""
        return next(iter(self.vehicles.values())).t_s

    @property
    def makespan_s(self) -> float:
        return float(self.t_s[-1]) if self.vehicles else 0.0


def _jsonable(value: Any) -> Any:
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return _jsonable(value.tolist())
    if isinstance(value, (np.floating, float)):
        v = float(value)
        return v if math.isfinite(v) else None
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, np.bool_):
        return bool(value)
    return value


def plan_to_dict(plan: PlanResult) -> dict:
    """The plan.json mapping (DESIGN keys plus the extra keys listed in the module docstring)."""
    return _jsonable(
        {
            "format_version": PLAN_FORMAT_VERSION,
            "scenario": plan.scenario,
            "dt_s": plan.dt_s,
            "method": plan.method,
            "vehicles": {
                name: {
                    "type": tr.type_name,
                    "t_s": np.round(tr.t_s, 6),
                    "position_m": np.round(tr.position_m, 6),
                    "velocity_mps": np.round(tr.velocity_mps, 6),
                    "acceleration_mps2": np.round(tr.acceleration_mps2, 6),
                }
                for name, tr in plan.vehicles.items()
            },
            "metrics": plan.metrics,
            "notes": list(plan.notes),
            "scenario_file": plan.scenario_file,
            "scenario_spec": plan.scenario_spec,
        }
    )


def write_plan(plan: PlanResult, out_dir: str | Path) -> Path:
    """Write ``out_dir/plan.json`` atomically; returns its path."""
    return atomic_write_text(Path(out_dir) / PLAN_FILENAME, json.dumps(plan_to_dict(plan), indent=1))


def _array(value: Any, where: str, shape_tail: tuple[int, ...]) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise UserError(f"{where}: expected numbers") from None
    if arr.ndim != 1 + len(shape_tail) or arr.shape[1:] != shape_tail or not np.all(np.isfinite(arr)):
        form = "[N] numbers" if not shape_tail else "[[x, y, z] x N] numbers"
        raise UserError(f"{where}: expected {form} (finite), got shape {arr.shape}")
    return arr


def plan_from_dict(doc: Any, *, label: str = "<plan>") -> PlanResult:
    """Validate a plan.json mapping into a :class:`PlanResult`; UserError naming the key."""
    if not isinstance(doc, dict):
        raise UserError(f"{label}: expected a JSON object with keys scenario, dt_s, vehicles, metrics")
    for key in ("scenario", "dt_s", "vehicles"):
        if key not in doc:
            raise UserError(f"{label}: {key}: missing; required plan.json key (DESIGN.md section 4)")
    dt = doc["dt_s"]
    if isinstance(dt, bool) or not isinstance(dt, (int, float)) or not dt > 0:
        raise UserError(f"{label}: dt_s: expected a positive number, got {dt!r}")
    if not isinstance(doc["vehicles"], dict) or not doc["vehicles"]:
        raise UserError(f"{label}: vehicles: expected a non-empty object NAME: {{type, t_s, position_m, ...}}")
    vehicles: dict[str, VehicleTrajectory] = {}
    grid = None
    for name, v in doc["vehicles"].items():
        where = f"{label}: vehicles.{name}"
        if not isinstance(v, dict):
            raise UserError(f"{where}: expected an object with type, t_s, position_m, velocity_mps, acceleration_mps2")
        for key in ("type", "t_s", "position_m", "velocity_mps", "acceleration_mps2"):
            if key not in v:
                raise UserError(f"{where}.{key}: missing; required plan.json key")
        t = _array(v["t_s"], f"{where}.t_s", ())
        arrays = [_array(v[k], f"{where}.{k}", (3,)) for k in ("position_m", "velocity_mps", "acceleration_mps2")]
        for key, arr in zip(("position_m", "velocity_mps", "acceleration_mps2"), arrays):
            if arr.shape[0] != t.shape[0]:
                raise UserError(f"{where}.{key}: expected {t.shape[0]} rows (one per t_s), got {arr.shape[0]}")
        if t.size < 1 or np.any(np.diff(t) <= 0):
            raise UserError(f"{where}.t_s: expected strictly increasing times")
        if grid is None:
            grid = t
        elif t.shape != grid.shape or not np.allclose(t, grid, atol=1e-6):
            raise UserError(f"{where}.t_s: expected the common time grid shared by every vehicle")
        vehicles[str(name)] = VehicleTrajectory(str(name), str(v["type"]), t, *arrays)
    metrics = doc.get("metrics") or {}
    if not isinstance(metrics, dict):
        raise UserError(f"{label}: metrics: expected an object")
    spec = doc.get("scenario_spec")
    return PlanResult(
        scenario=str(doc["scenario"]),
        dt_s=float(dt),
        vehicles=vehicles,
        metrics=dict(metrics),
        method=str(doc.get("method", "unknown")),
        notes=[str(n) for n in doc.get("notes") or []],
        scenario_file=doc.get("scenario_file"),
        scenario_spec=spec if isinstance(spec, dict) else None,
    )


def read_plan(path: str | Path) -> PlanResult:
    """Read a plan.json (or a folder holding one); UserError on a missing or malformed file."""
    path = Path(path)
    if path.is_dir():
        path = path / PLAN_FILENAME
    doc = read_json(path, what="plan file")
    return plan_from_dict(doc, label=str(path))
