"""The plan.json format, declared (:class:`PlanFile`; the rules are in :mod:`proxplan.planfile.plan`).

Trajectory arrays are read with numpy in one call each (a swarm plan holds thousands of samples per
vehicle) and checked for shape and finiteness; the model checks what one vehicle or the file alone
can tell (rows per sample, one uniform time grid of step ``dt_s`` shared by every vehicle, the
format version, vehicle types present in format 2). Which type each vehicle names is resolved when
the :class:`~proxplan.planfile.plan.Plan` is built.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Annotated, Any

import numpy as np
from pydantic import Field, PlainValidator, WithJsonSchema, field_validator, model_validator

from proxplan.fileio import FileModel, Flag, Name, Number, Positive, Text, Whole, optional, problem
from proxplan.physics import VehicleEntry
from proxplan.planfile.scenario_model import ScenarioFile

PLAN_FORMAT_VERSION = 2
READABLE_FORMAT_VERSIONS = (1, 2)
GRID_TOLERANCE_S = 1e-6  # common-grid and time-step tolerance, s

_POINT = {"type": "array", "items": {"type": "number"}, "minItems": 3, "maxItems": 3}


def _reader(columns: int | None) -> Callable[[Any], np.ndarray]:
    """Read an array with numpy: (N,) numbers (``columns`` None) or (N, 3) rows [x, y, z]."""
    form = "[N] numbers" if columns is None else "[[x, y, z] x N] numbers"
    tail: tuple[int, ...] = () if columns is None else (columns,)

    def read(value: Any) -> np.ndarray:
        try:
            arr = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise problem(f"expected {form}") from None
        if arr.ndim != 1 + len(tail) or arr.shape[1:] != tail:
            raise problem(f"expected {form}, got shape {arr.shape}")
        bad = np.flatnonzero(~np.isfinite(arr.reshape(arr.shape[0], -1)).all(axis=1))
        if bad.size:
            raise problem(f"sample {int(bad[0])} is not finite (NaN or infinity); expected finite {form}")
        return arr

    return read


Times = Annotated[
    np.ndarray, PlainValidator(_reader(None)), WithJsonSchema({"type": "array", "items": {"type": "number"}})
]
"""(N,) finite numbers, read by numpy."""
Points = Annotated[np.ndarray, PlainValidator(_reader(3)), WithJsonSchema({"type": "array", "items": _POINT})]
"""(N, 3) finite rows [x, y, z], read by numpy."""
ROWS = ("position_m", "velocity_mps", "acceleration_mps2", "disturbance_force_N", "disturbance_torque_Nm")


class TrajectoryPart(FileModel):
    """One vehicle's plan sampled on the common time grid (world frame, z up)."""

    type: Annotated[Text, Field(min_length=1)] = Field(description="vehicle type (a key of vehicle_types)")
    t_s: Times = Field(description="sample times, s: N >= 2, strictly increasing, step dt_s")
    position_m: Points = Field(description="centre-of-mass positions, (N, 3), m")
    velocity_mps: Points = Field(description="velocities, (N, 3), m/s")
    acceleration_mps2: Points = Field(description="accelerations, (N, 3), m/s^2")
    disturbance_force_N: Points | None = optional("predicted disturbance force (feed-forward), (N, 3), N")
    disturbance_torque_Nm: Points | None = optional("predicted disturbance torque (feed-forward), (N, 3), N m")

    @model_validator(mode="after")
    def _one_row_per_time(self) -> TrajectoryPart:
        n = self.t_s.shape[0]
        for key in ROWS:
            arr = getattr(self, key)
            if arr is not None and arr.shape[0] != n:
                raise problem(f"expected {n} rows (one per t_s), got {arr.shape[0]}", at=key)
        if n < 2 or np.any(np.diff(self.t_s) <= 0):
            raise problem("expected at least two strictly increasing times", at="t_s")
        return self


class SolverPart(FileModel):
    """What the optimiser (CasADi / IPOPT) reported (``proxplan plan --method optimized``)."""

    method: Text = Field(description="joint (one problem) or decomposed (one vehicle at a time)")
    converged: Flag = Field(description="IPOPT converged and the result passed the verifier")
    return_status: Text = Field(description="IPOPT's return status of the last solve")
    iterations: Whole = Field(description="IPOPT iterations over all solves")
    solves: Whole = Field(description="IPOPT solves")
    solve_time_s: Number = Field(description="wall time in IPOPT, s")
    constraint_violation: Number | None = Field(description="largest constraint violation of the last solve")
    objective: Number | None = Field(description="objective value of the last solve")


class PlanFile(FileModel):
    """A plan.json: every vehicle's trajectory on one time grid, the vehicle types and the scenario."""

    format_version: Whole = optional(
        f"plan format, one of {', '.join(map(str, READABLE_FORMAT_VERSIONS))} (absent: 1)",
        json_schema_extra={"enum": list(READABLE_FORMAT_VERSIONS)},
    )
    scenario: Text = Field(description="scenario name")
    dt_s: Positive = Field(description="step of the common time grid, s")
    method: Text = optional("planning method (optimized, sampling, swarm, ...)")
    vehicles: Annotated[dict[Name, TrajectoryPart], Field(min_length=1)] = Field(
        description="every vehicle's trajectory by name"
    )
    vehicle_types: dict[Name, VehicleEntry] = optional(
        "every used type's parameters (the vehicle-file form); required in format 2"
    )
    metrics: dict[Text, Any] | None = optional("planning_time_s, max_authority_usage, ...")
    notes: list[Text] | None = optional("what the user should know about the plan")
    scenario_file: Text | None = optional("absolute path of the scenario YAML, or null")
    scenario_spec: ScenarioFile | None = optional("the normalised, self-contained scenario")
    solver: SolverPart | None = optional("the optimiser's statistics (method optimized), else null")

    @property
    def version(self) -> int:
        return 1 if self.format_version is None else self.format_version

    @field_validator("format_version")
    @classmethod
    def _readable(cls, version: int) -> int:
        if version not in READABLE_FORMAT_VERSIONS:
            raise problem(
                f"{version!r} is not a plan format this proxplan reads; expected one of "
                f"{', '.join(map(str, READABLE_FORMAT_VERSIONS))} (re-plan with this version)"
            )
        return version

    @model_validator(mode="after")
    def _one_grid(self) -> PlanFile:
        if self.version >= 2 and not self.vehicle_types:
            raise problem("expected an object TYPE: {vehicle parameters} (format 2)", at="vehicle_types")
        grid = None
        for name, v in self.vehicles.items():
            steps = np.diff(v.t_s)
            off = np.flatnonzero(np.abs(steps - self.dt_s) > GRID_TOLERANCE_S + 1e-9 * self.dt_s)
            if off.size:
                k = int(off[0])
                raise problem(
                    f"step {steps[k]:.6g} s between samples {k} and {k + 1} differs from dt_s = {self.dt_s:g} s; "
                    "expected a uniform grid",
                    at=("vehicles", name, "t_s"),
                )
            if grid is None:
                grid = v.t_s
            elif v.t_s.shape != grid.shape or not np.allclose(v.t_s, grid, atol=GRID_TOLERANCE_S, rtol=0.0):
                raise problem("expected the common time grid shared by every vehicle", at=("vehicles", name, "t_s"))
        return self
