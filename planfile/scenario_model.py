"""The scenario file format, declared (:class:`ScenarioFile`): every key, its form, unit and default.

Frame: world, z up, metres. A scenario file::

    # yaml-language-server: $schema=../schemas/scenario.json
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
    assign_goals: by_type                       # optional: vehicles of one type may swap goals
    vehicles:
      carrier: {type: large-quad, start: [0, 0, 1.5], hover: true}
      shuttle: {type: small-quad, start: [2, 1, 2.5], dock: {with: carrier, offset: [0, 0, 0.4]}}
      other:   {type: small-quad, start: [-2, 0, 1], goal: [2, 0, 1], max_speed_mps: 1.0}

The model checks what one key (or one vehicle) can tell alone; what needs other files or the whole
scenario (vehicle types, dock partners, points inside the workspace) is checked when the
:class:`~proxplan.planfile.scenario.Scenario` is built (:mod:`proxplan.planfile.scenario_load`).
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

from pydantic import Field, field_validator, model_validator

from proxplan.fileio import FileModel, Flag, Name, Number, Text, Vec3, optional, problem
from proxplan.physics import BUILTIN_VEHICLES, ModelOptionsPart

MAX_VEHICLES = 1000
"""Largest swarm a scenario may hold (the planners' limit)."""
InvalidZoneRule = Literal["conservative", "model", "forbid"]
"""How the planner treats 0 < dz <= 3 L of a source where the field model is not valid (S0 II-A):
``conservative`` (default) uses the cost map's conservative cutoff there; ``model`` uses the
model's extrapolated numbers; ``forbid`` keeps targets out of the whole invalid cylinder."""
AssignGoals = Literal["by_type"]
"""Accepted values of ``assign_goals``: ``by_type`` lets vehicles of one type take each other's goals."""

Text1 = Annotated[Text, Field(min_length=1)]
Name1 = Annotated[Name, Field(min_length=1)]
"""A vehicle or type name (written as a number in YAML it is taken as its text, like a mapping key)."""


class BoxPart(FileModel):
    """An axis-aligned box, world frame, m."""

    min: Vec3 = Field(description="lowest corner [x, y, z], world frame, m")
    max: Vec3 = Field(description="highest corner [x, y, z], world frame, m (above min on every axis)")
    name: Text = optional("a name for messages and the review app")

    @model_validator(mode="after")
    def _max_above_min(self) -> BoxPart:
        if any(hi <= lo for lo, hi in zip(self.min, self.max)):
            raise problem(f"expected max > min on every axis, got min {list(self.min)} max {list(self.max)}")
        return self


class LimitsPart(FileModel):
    """Scenario-wide limits (each optional; :class:`proxplan.planfile.Limits` holds the defaults)."""

    authority_fraction: Annotated[Number, Field(gt=0, le=1)] = optional(
        "cap on every vehicle's authority usage (DESIGN.md section 3), - (default 0.5)"
    )
    min_separation_m: Annotated[Number, Field(gt=0, le=10)] = optional(
        "least centre-to-centre distance of two vehicles, m (default 0.25; docks exempt at the dock)"
    )
    invalid_zone_rule: InvalidZoneRule = optional(
        "the zone 0 < dz <= 3 L below a source, where the field model does not hold: conservative "
        "(default, the cost map's conservative cut-off), model (its extrapolated numbers) or forbid (stay out)",
    )
    obstacle_margin_m: Annotated[Number, Field(ge=0, lt=10)] = optional(
        "inflation of obstacles beyond the vehicle's body radius, m (default 0.05)"
    )
    time_horizon_s: Annotated[Number, Field(gt=0, le=600)] = optional(
        "longest plan the sampler searches, s (default 60)"
    )
    tracking_margin_m: Annotated[Number, Field(ge=0, lt=1)] = optional(
        "tracking tube: how far a vehicle may be off its plan when flown, m (default: the largest "
        "measured tube of the scenario's vehicle types)",
    )


class DockPart(FileModel):
    """A dock: the goal is another vehicle's final position plus an offset."""

    with_: Name1 = Field(alias="with", description="the vehicle to dock with")
    offset: Vec3 = Field(description="dock point minus that vehicle's final position [x, y, z], world frame, m")


class TaskPart(FileModel):
    """One vehicle: its type, start and exactly one task (goal, hover or dock)."""

    type: Name1 = Field(
        description="vehicle type: built-in (proxplan vehicles) or from vehicle_file / model_file",
        json_schema_extra={"examples": list(BUILTIN_VEHICLES)},
    )
    start: Vec3 = Field(description="start position of the centre of mass [x, y, z], world frame, m")
    goal: Vec3 | None = optional("goal position [x, y, z], world frame, m")
    hover: Flag | None = optional("true: stay at the start")
    dock: DockPart | None = optional("dock with another vehicle: {with: NAME, offset: [x, y, z]}")
    max_speed_mps: Annotated[Number, Field(gt=0, le=20)] = optional("speed limit, m/s (default: the type's)")
    max_accel_mps2: Annotated[Number, Field(gt=0, le=30)] = optional("acceleration limit, m/s^2 (default: the type's)")
    max_jerk_mps3: Annotated[Number, Field(gt=0, le=500)] = optional("jerk limit, m/s^3 (default: the type's)")

    @property
    def tasks(self) -> list[str]:
        """The tasks given (``hover: false`` and null count as not given)."""
        return [
            k for k, v in (("goal", self.goal), ("hover", self.hover), ("dock", self.dock)) if v not in (None, False)
        ]

    @model_validator(mode="after")
    def _one_task(self) -> TaskPart:
        if len(self.tasks) != 1:
            raise problem(
                "expected exactly one of 'goal: [x, y, z]', 'hover: true' or 'dock: {with: NAME, offset: [x, y, z]}', "
                f"got {self.tasks or 'none'}"
            )
        return self


def _vehicle_count(schema: dict[str, Any]) -> None:
    schema.update(minProperties=1, maxProperties=MAX_VEHICLES)


class ScenarioFile(FileModel):
    """A scenario: workspace, obstacles, limits and vehicles with their tasks (``proxplan plan``)."""

    name: Text1 = optional("scenario name (default: the file name without .yaml)")
    description: Text = optional("what the scenario tests")
    vehicle_file: Text1 = optional("a vehicle file of custom types, relative to this file")
    model_file: Text1 = optional("a calibrated model file (proxplan identify --save-model), relative to this file")
    model: ModelOptionsPart | None = optional(
        "disturbance-model options; they override model_file's, its effects are added"
    )
    workspace: BoxPart = Field(description="the box every vehicle stays in, world frame, m")
    obstacles: list[BoxPart] | None = optional("axis-aligned box obstacles, world frame, m")
    limits: LimitsPart | None = optional("scenario-wide limits")
    assign_goals: AssignGoals | None = optional(
        "by_type: vehicles of one type may take each other's goals (formation changes); absent: "
        "each vehicle flies to its own goal",
    )
    vehicles: Annotated[dict[Name, TaskPart], Field(json_schema_extra=_vehicle_count)] = Field(
        description=f"the vehicles by name (1..{MAX_VEHICLES}), in planning order"
    )

    @field_validator("vehicles", mode="before")
    @classmethod
    def _vehicle_count(cls, value: Any) -> Any:
        if isinstance(value, dict) and not value:
            raise problem("expected at least one vehicle")
        if isinstance(value, dict) and len(value) > MAX_VEHICLES:
            raise problem(f"expected at most {MAX_VEHICLES} vehicles, got {len(value)} (split the swarm into groups)")
        return value
