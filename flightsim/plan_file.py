"""Plan arrays for the simulator and a small plan.json reader (DESIGN.md section 4).

flightsim may import only costmaps (no import cycle with planner), so it reads plan.json itself.
Any object with the same attribute names (e.g. planner's ``PlanResult``) is accepted by the
simulator. Positions world frame (z up), m; velocities m/s; accelerations m/s^2; times s.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from fileio.errors import UserError


@dataclass(frozen=True)
class TrajectoryArrays:
    """One vehicle's reference: ``t_s`` (N,), ``position_m``/``velocity_mps``/``acceleration_mps2`` (N, 3)."""

    name: str
    type_name: str
    t_s: np.ndarray
    position_m: np.ndarray
    velocity_mps: np.ndarray
    acceleration_mps2: np.ndarray

    def state_at(self, t_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Linearly interpolated reference (3,) x3 at time ``t_s``; after the end the vehicle hovers
        at the last position (zero velocity and acceleration), before the start at the first."""
        if t_s >= self.t_s[-1]:
            return self.position_m[-1], np.zeros(3), np.zeros(3)
        if t_s <= self.t_s[0]:
            return self.position_m[0], np.zeros(3), np.zeros(3)
        i = int(np.searchsorted(self.t_s, t_s, side="right")) - 1
        a = (t_s - self.t_s[i]) / (self.t_s[i + 1] - self.t_s[i])
        out = []
        for arr in (self.position_m, self.velocity_mps, self.acceleration_mps2):
            out.append((1.0 - a) * arr[i] + a * arr[i + 1])
        return out[0], out[1], out[2]


@dataclass(frozen=True)
class PlanArrays:
    """A multi-vehicle plan on one time grid."""

    scenario: str
    dt_s: float
    vehicles: dict[str, TrajectoryArrays]
    metrics: dict[str, Any] = field(default_factory=dict)


def trajectory(name: str, type_name: str, t_s, position_m, velocity_mps=None, acceleration_mps2=None) -> TrajectoryArrays:
    """Build a :class:`TrajectoryArrays`; missing velocity/acceleration are finite differences."""
    t = np.asarray(t_s, dtype=float)
    p = np.asarray(position_m, dtype=float)
    v = np.gradient(p, t, axis=0) if velocity_mps is None else np.asarray(velocity_mps, dtype=float)
    a = np.gradient(v, t, axis=0) if acceleration_mps2 is None else np.asarray(acceleration_mps2, dtype=float)
    return TrajectoryArrays(name, type_name, t, p, v, a)


def _array(value: Any, where: str, n: int | None) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise UserError(f"{where}: expected numbers") from None
    want = "(N,)" if n is None else f"({n}, 3)"
    if (n is None and arr.ndim != 1) or (n is not None and arr.shape != (n, 3)) or not np.all(np.isfinite(arr)):
        raise UserError(f"{where}: expected a finite array of shape {want}, got shape {arr.shape}")
    return arr


def read_plan_file(path: str | Path) -> PlanArrays:
    """Read and validate a plan.json; UserError naming the file and key on any problem."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text())
    except OSError as err:
        raise UserError(f"{path}: cannot read plan ({err.strerror})") from None
    except json.JSONDecodeError as err:
        raise UserError(f"{path}: not valid JSON ({err.msg} at line {err.lineno})") from None
    if not isinstance(doc, dict) or not isinstance(doc.get("vehicles"), dict) or not doc["vehicles"]:
        raise UserError(f"{path}: vehicles: expected a non-empty object NAME: {{type, t_s, position_m, velocity_mps, acceleration_mps2}}")
    dt = doc.get("dt_s")
    if not isinstance(dt, (int, float)) or not dt > 0:
        raise UserError(f"{path}: dt_s: expected a positive number, got {dt!r}")
    vehicles = {}
    for name, v in doc["vehicles"].items():
        where = f"{path}: vehicles.{name}"
        if not isinstance(v, dict) or not isinstance(v.get("type"), str):
            raise UserError(f"{where}.type: expected a vehicle type name")
        for key in ("t_s", "position_m", "velocity_mps", "acceleration_mps2"):
            if key not in v:
                raise UserError(f"{where}.{key}: missing; required plan.json key (DESIGN.md section 4)")
        t = _array(v["t_s"], f"{where}.t_s", None)
        if t.size < 2 or np.any(np.diff(t) <= 0):
            raise UserError(f"{where}.t_s: expected at least two strictly increasing times")
        vehicles[str(name)] = TrajectoryArrays(
            str(name), v["type"], t,
            _array(v["position_m"], f"{where}.position_m", t.size),
            _array(v["velocity_mps"], f"{where}.velocity_mps", t.size),
            _array(v["acceleration_mps2"], f"{where}.acceleration_mps2", t.size),
        )
    metrics = doc.get("metrics") if isinstance(doc.get("metrics"), dict) else {}
    return PlanArrays(str(doc.get("scenario", path.stem)), float(dt), vehicles, metrics)
