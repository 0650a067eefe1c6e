"""The plan.json contract (DESIGN.md section 4): one reader, one writer, one trajectory sampler.

Every user of a plan (planner, verifier, simulator, web app, exporters) reads, writes and samples
plans through this module, so they agree on the rules:

* ``format_version`` 2 (written) and 1 (read: vehicle types resolved by name from the built-in
  types, a note says so). Any other version is a one-line :class:`~proxplan.fileio.errors.UserError`.
* Every vehicle on one common time grid ``t_s`` (N >= 2 samples, strictly increasing, step
  ``dt_s``), with finite ``position_m``, ``velocity_mps``, ``acceleration_mps2`` (N, 3), world
  frame (z up); m, m/s, m/s^2, s.
* Sampling between grid points is quintic Hermite interpolation of position, velocity and
  acceleration (exact for the piecewise cubic/quintic trajectories the planner produces, C2
  everywhere); before the first and after the last sample the vehicle rests at its first / last
  position (zero velocity and acceleration).
* A plan stands alone: ``vehicle_types`` holds every used type's full parameters (the vehicle-YAML
  form of :func:`proxplan.physics.vehicle_yaml.vehicle_to_yaml_dict`), ``scenario_spec`` the normalised,
  self-contained scenario (workspace, obstacles, limits, model options, tasks;
  :meth:`proxplan.planfile.scenario.Scenario.to_spec`).

plan.json keys: ``format_version``, ``scenario`` (name), ``dt_s``, ``method``, ``vehicles: {NAME:
{type, t_s, position_m, velocity_mps, acceleration_mps2}}``, ``vehicle_types: {TYPE: {...}}``,
``metrics: {planning_time_s, max_authority_usage, min_separation_m, makespan_s, ...}``, ``notes``,
``scenario_file`` (absolute path of the scenario YAML, or null), ``scenario_spec``. The model the
plan was made with travels in ``scenario_spec.model``: ``field_form`` and ``effects`` (the
calibrated model's effects between vehicles with every parameter, ``[{name, params}]``;
:attr:`Plan.effects`).

Optimiser statistics (optional, ``solver``; written by ``proxplan plan --method optimized``, null
otherwise): ``{method, converged, return_status, iterations, solves, solve_time_s,
constraint_violation, objective}`` (:class:`SolverStats`), IPOPT's own numbers for the solve the
plan came from (or, after a fall-back to the sampling plan, for the attempt that failed).

Feed-forward (optional per vehicle, written by ``proxplan plan``): ``disturbance_force_N`` and
``disturbance_torque_Nm`` (N, 3), the disturbance wrench the model predicts on the vehicle at each
``t_s`` (world frame, level vehicle; ``proxplan.verify.wrench_along_plan``). Plans without them (older
files) read with ``None``; users recompute them and say so (``proxplan simulate --feedforward``).
"""

from __future__ import annotations

import functools
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from proxplan.fileio import UserError, atomic_write_text, read_json, validate
from proxplan.physics import (
    BUILTIN_VEHICLES,
    Effect,
    Vehicle,
    build_vehicles,
    effects_from_list,
    vehicle_from_dict,
    vehicle_to_yaml_dict,
)
from proxplan.planfile.plan_model import PLAN_FORMAT_VERSION, PlanFile, SolverPart

PLAN_FILENAME = "plan.json"
# how plan.json is written: compact JSON (no indent, no space after separators), so that json's C
# encoder writes it (an indent makes json use its pure-Python encoder: corridor-64's plan 0.48 s of
# CPU against 0.07 s, 6.2 MB against 2.4 MB; grid-256's 4.9 s, stop 62 round 24A). Only the layout
# of the text: a reader parses any JSON layout, so plans written indented read as before
PLAN_JSON_SEPARATORS = (",", ":")

# quintic Hermite: p(s) = sum_k s^k (C @ [p0, h v0, h^2 a0, p1, h v1, h^2 a1])_k, s in [0, 1]
_QUINTIC = np.array(
    [
        [1.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 0.5, 0.0, 0.0, 0.0],
        [-10.0, -6.0, -1.5, 10.0, -4.0, 0.5],
        [15.0, 8.0, 1.5, -15.0, 7.0, -1.0],
        [-6.0, -3.0, -0.5, 6.0, -3.0, 0.5],
    ]
)


@dataclass(frozen=True)
class VehicleTrajectory:
    """One vehicle's plan sampled at ``t_s`` (N,), s: ``position_m``, ``velocity_mps`` and
    ``acceleration_mps2`` (N, 3), world frame. ``vehicle`` holds every parameter of its type."""

    name: str
    type_name: str
    vehicle: Vehicle
    t_s: np.ndarray
    position_m: np.ndarray
    velocity_mps: np.ndarray
    acceleration_mps2: np.ndarray
    disturbance_force_N: np.ndarray | None = None  # (N, 3) predicted, world frame, N (feed-forward)
    disturbance_torque_Nm: np.ndarray | None = None  # (N, 3) predicted, world axes, N m

    def __getstate__(self) -> dict[str, Any]:
        """The fields only (a pickle, e.g. to a Dask worker, leaves out the cached coefficients)."""
        state = dict(self.__dict__)
        state.pop("_coefficients", None)
        return state

    @property
    def has_feedforward(self) -> bool:
        return self.disturbance_force_N is not None and self.disturbance_torque_Nm is not None

    def _pieces(self, t_s) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """For times ``t_s`` (M,): quintic coefficients (M, 6, 3) of s^0..s^5 of the grid interval
        holding each time, s in [0, 1] (M,), interval lengths (M, 1), s, and the mask of times
        outside the plan (M,)."""
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        grid = self.t_s
        k = np.clip(np.searchsorted(grid, t, side="right") - 1, 0, grid.size - 2)
        h = grid[k + 1] - grid[k]
        s = np.clip((t - grid[k]) / h, 0.0, 1.0)
        return self._coefficients[k], s, h[:, None], (t < grid[0]) | (t > grid[-1])

    @functools.cached_property
    def _coefficients(self) -> np.ndarray:
        """Quintic coefficients (N - 1, 6, 3) of s^0..s^5 of every grid interval, computed once per
        trajectory (its arrays are not changed after it is built: the class is frozen): sampling
        a plan many times (the verifier, the tracking prediction) indexes them."""
        grid = self.t_s
        hh = (grid[1:] - grid[:-1])[:, None]
        data = np.stack(
            [
                self.position_m[:-1],
                hh * self.velocity_mps[:-1],
                hh**2 * self.acceleration_mps2[:-1],
                self.position_m[1:],
                hh * self.velocity_mps[1:],
                hh**2 * self.acceleration_mps2[1:],
            ],
            axis=1,
        )  # (N - 1, 6, 3)
        return np.einsum("ij,mjd->mid", _QUINTIC, data)

    def sample(self, t_s: np.ndarray | float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(position_m, velocity_mps, acceleration_mps2), each (M, 3), at times ``t_s`` (M,), s.

        Quintic Hermite between samples; at rest at the first / last position outside the plan.
        """
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        if self.t_s.size < 2:
            p = np.repeat(self.position_m[:1], t.size, axis=0)
            return p, np.zeros_like(p), np.zeros_like(p)
        coef, s, hh, outside = self._pieces(t)
        powers = s[:, None] ** np.arange(6)[None, :]  # (M, 6)
        d_powers = np.zeros_like(powers)
        d_powers[:, 1:] = np.arange(1, 6) * powers[:, :5]
        dd_powers = np.zeros_like(powers)
        dd_powers[:, 2:] = np.arange(2, 6) * np.arange(1, 5) * powers[:, :4]
        p = np.einsum("mi,mid->md", powers, coef)
        v = np.einsum("mi,mid->md", d_powers, coef) / hh
        a = np.einsum("mi,mid->md", dd_powers, coef) / hh**2
        v[outside] = 0.0
        a[outside] = 0.0
        return p, v, a

    def jerk_at(self, t_s: np.ndarray | float) -> np.ndarray:
        """Jerk (M, 3), m/s^3, at ``t_s`` (M,), s: the third derivative of the same quintic Hermite
        interpolant as :meth:`sample` (exact for the cubic pieces of Ruckig's jerk-limited profiles
        inside a grid interval; zero outside the plan). The reference's angular-rate feed-forward
        (differential flatness, :mod:`proxplan.flightsim.mellinger`) is computed from it."""
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        if self.t_s.size < 2:
            return np.zeros((t.size, 3))
        coef, s, hh, outside = self._pieces(t)
        ddd = np.zeros((t.size, 6))  # d^3/ds^3 of s^0..s^5
        ddd[:, 3] = 6.0
        ddd[:, 4] = 24.0 * s
        ddd[:, 5] = 60.0 * s**2
        j = np.einsum("mi,mid->md", ddd, coef) / hh**3
        j[outside] = 0.0
        return j

    def position_at(self, t_s: np.ndarray | float) -> np.ndarray:
        """Positions (M, 3), m, at ``t_s`` (M,), s (see :meth:`sample`)."""
        return self.sample(t_s)[0]


@dataclass(frozen=True)
class SolverStats:
    """What the trajectory optimiser (CasADi / IPOPT) reported for the solve a plan came from."""

    method: str  # "joint" (one problem of all moving vehicles) or "decomposed" (one vehicle at a time)
    converged: bool  # IPOPT converged and the result passed the verifier
    return_status: str  # IPOPT's return status of the last solve (e.g. "Solve_Succeeded")
    iterations: int  # IPOPT iterations over all solves
    solves: int  # IPOPT solves (linearisation rounds, passes, decomposed solves)
    solve_time_s: float  # wall time in IPOPT, s
    constraint_violation: float  # largest constraint violation of the last solve's NLP (its units: m, -, ...)
    objective: float  # objective value of the last solve (makespan s + weighted smoothness and exposure)

    def to_dict(self) -> dict[str, Any]:
        return {
            "method": self.method,
            "converged": self.converged,
            "return_status": self.return_status,
            "iterations": int(self.iterations),
            "solves": int(self.solves),
            "solve_time_s": round(float(self.solve_time_s), 4),
            "constraint_violation": float(self.constraint_violation),
            "objective": float(self.objective),
        }

    @staticmethod
    def from_part(part: SolverPart) -> SolverStats:
        """The statistics of a validated ``solver`` entry (null numbers read as NaN)."""
        nan = float("nan")
        return SolverStats(
            method=part.method,
            converged=part.converged,
            return_status=part.return_status,
            iterations=part.iterations,
            solves=part.solves,
            solve_time_s=part.solve_time_s,
            constraint_violation=nan if part.constraint_violation is None else part.constraint_violation,
            objective=nan if part.objective is None else part.objective,
        )


@dataclass
class Plan:
    """A multi-vehicle plan: every trajectory on one common time grid of step ``dt_s``, s."""

    scenario: str
    dt_s: float
    vehicles: dict[str, VehicleTrajectory]
    metrics: dict[str, Any] = field(default_factory=dict)
    method: str = "sampling"
    notes: list[str] = field(default_factory=list)
    scenario_file: str | None = None
    scenario_spec: dict | None = None
    format_version: int = PLAN_FORMAT_VERSION
    solver: SolverStats | None = None  # the optimiser's statistics (method "optimized"), else None
    # the planner ran the verifier on this very plan in this process and it passed (not written to
    # plan.json: a plan read from a file is checked again by whoever needs the verdict)
    verified: bool = False

    @property
    def t_s(self) -> np.ndarray:
        """The common time grid (N,), s."""
        return next(iter(self.vehicles.values())).t_s

    @property
    def makespan_s(self) -> float:
        return float(self.t_s[-1]) if self.vehicles else 0.0

    @property
    def vehicle_types(self) -> dict[str, Vehicle]:
        """Type name -> vehicle parameters of every type the plan uses."""
        out: dict[str, Vehicle] = {}
        for tr in self.vehicles.values():
            known = out.setdefault(tr.type_name, tr.vehicle)
            if known != tr.vehicle:
                raise ValueError(f"vehicle type {tr.type_name!r} has two different parameter sets in one plan")
        return out

    @property
    def effects(self) -> tuple[Effect, ...]:
        """The effects between vehicles the plan was made with (``scenario_spec.model.effects``)."""
        model = (self.scenario_spec or {}).get("model") or {}
        return effects_from_list(model.get("effects"), "plan.json: scenario_spec.model.effects")

    def positions_at(self, t_s: np.ndarray) -> dict[str, np.ndarray]:
        """Every vehicle's positions (M, 3), m, at ``t_s`` (M,), s."""
        return {name: tr.position_at(t_s) for name, tr in self.vehicles.items()}


def jsonable(value: Any) -> Any:
    """``value`` with numpy arrays and scalars turned into JSON types (non-finite floats -> None)."""
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        if value.dtype.kind in "biu" or (value.dtype.kind == "f" and bool(np.isfinite(value).all())):
            return value.tolist()  # already JSON types (Python bools, ints, finite floats): nothing to turn
        return jsonable(value.tolist())
    if isinstance(value, (np.floating, float)):
        v = float(value)
        return v if math.isfinite(v) else None
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.bool_):
        return bool(value)
    return value


def plan_to_dict(plan: Plan) -> dict:
    """The plan.json mapping of ``plan`` (format version :data:`PLAN_FORMAT_VERSION`)."""
    return jsonable(
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
                    **(
                        {
                            "disturbance_force_N": np.round(tr.disturbance_force_N, 7),
                            "disturbance_torque_Nm": np.round(tr.disturbance_torque_Nm, 8),
                        }
                        if tr.disturbance_force_N is not None and tr.disturbance_torque_Nm is not None
                        else {}
                    ),
                }
                for name, tr in plan.vehicles.items()
            },
            "vehicle_types": {name: vehicle_to_yaml_dict(v) for name, v in plan.vehicle_types.items()},
            "metrics": plan.metrics,
            "notes": list(plan.notes),
            "scenario_file": plan.scenario_file,
            "scenario_spec": plan.scenario_spec,
            "solver": None if plan.solver is None else plan.solver.to_dict(),
        }
    )


def write_plan(plan: Plan, out_dir: str | Path) -> Path:
    """Write ``out_dir/plan.json`` atomically, compact (:data:`PLAN_JSON_SEPARATORS`); returns its path."""
    text = json.dumps(plan_to_dict(plan), separators=PLAN_JSON_SEPARATORS)
    return atomic_write_text(Path(out_dir) / PLAN_FILENAME, text)


def plan_vehicle_types(doc: Any, label: str = "<plan>") -> dict[str, Vehicle]:
    """The vehicle types a plan.json mapping carries (format 1: the built-in types), validated; for
    a plan without its samples (an export manifest's ``plan``)."""
    if not isinstance(doc, dict):
        raise UserError(f"{label}: expected a JSON object with keys scenario, dt_s, vehicles, metrics")
    if doc.get("format_version", 1) == 1:
        return dict(BUILTIN_VEHICLES)
    raw = doc.get("vehicle_types")
    if not isinstance(raw, dict) or not raw:
        raise UserError(f"{label}: vehicle_types: expected an object TYPE: {{vehicle parameters}} (format 2)")
    return {str(n): vehicle_from_dict(str(n), d, source=f"{label}: vehicle_types") for n, d in raw.items()}


def plan_from_dict(doc: Any, *, label: str = "<plan>") -> Plan:
    """Validate a plan.json mapping into a :class:`Plan`; UserError naming the key otherwise."""
    pf = validate(PlanFile, doc, label=label)
    if pf.version == 1:
        types = dict(BUILTIN_VEHICLES)
    else:
        types = build_vehicles(pf.vehicle_types or {}, source=f"{label}: vehicle_types")
    vehicles: dict[str, VehicleTrajectory] = {}
    for name, v in pf.vehicles.items():
        if v.type not in types:
            raise UserError(
                f"{label}: vehicles.{name}.type: unknown vehicle type {v.type!r}; expected one of the plan's "
                f"vehicle types ({', '.join(types)})"
            )
        vehicles[name] = VehicleTrajectory(
            name, v.type, types[v.type], v.t_s, v.position_m, v.velocity_mps, v.acceleration_mps2,
            v.disturbance_force_N, v.disturbance_torque_Nm,
        )  # fmt: skip
    notes = list(pf.notes or [])
    if pf.version == 1:
        notes.append(f"{label}: plan format 1: vehicle types resolved by name from the built-in types")
    return Plan(
        scenario=pf.scenario,
        dt_s=float(pf.dt_s),
        vehicles=vehicles,
        metrics=dict(pf.metrics or {}),
        method=pf.method or "unknown",
        notes=notes,
        scenario_file=pf.scenario_file,
        scenario_spec=doc.get("scenario_spec"),
        format_version=pf.version,
        solver=None if pf.solver is None else SolverStats.from_part(pf.solver),
    )


def plan_path(path: str | Path) -> Path:
    """``path`` itself, or ``path/plan.json`` when it is a folder."""
    path = Path(path)
    return path / PLAN_FILENAME if path.is_dir() else path


def read_plan(path: str | Path) -> Plan:
    """Read a plan.json (or a folder holding one); UserError on a missing or malformed file."""
    path = plan_path(path)
    return plan_from_dict(read_json(path, what="plan file"), label=str(path))
