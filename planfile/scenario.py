"""The validated scenario (DESIGN.md section 4) as frozen dataclasses, with what follows from it: the
tracking tube, final positions, dock geometry and order, and the self-contained spec plan.json keeps.

Frame: world, z up, metres. The file format is declared in :mod:`proxplan.planfile.scenario_model`
and read by :func:`proxplan.planfile.scenario_load.load_scenario`.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, get_args

import numpy as np

from proxplan.physics import DEFAULT_TRACKING_TUBE_M, VALIDITY_FACTOR_L, Effect, KinematicLimits, Vehicle
from proxplan.planfile.scenario_model import InvalidZoneRule

TRACKING_MARGIN_M = DEFAULT_TRACKING_TUBE_M
"""Tube radius, m, of :class:`Limits` built without vehicles (a scenario file without
``limits.tracking_margin_m`` takes :func:`scenario_tube_m` of its vehicles instead)."""


def scenario_tube_m(tasks: Mapping[str, VehicleTask]) -> float:
    """The tube of a scenario whose limits do not set one, m: the largest tracking tube of its
    vehicles' types (``Vehicle.tracking_tube_m``, measured per type by ``proxplan track-limits``).
    Planner and verifier apply one tube per scenario; the largest covers every vehicle."""
    return max(float(t.vehicle.tracking_tube_m) for t in tasks.values())


DOCK_APPROACH_MARGIN_M = 0.1  # a dock approach point lies this far beyond the invalid zone, m
INVALID_ZONE_RULES: tuple[str, ...] = get_args(InvalidZoneRule)
"""How the planner treats the zone where the field model is not valid (:data:`InvalidZoneRule`)."""


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
    assign_goals: str | None = None  # "by_type": vehicles of one type may take each other's goals; None: fixed goals

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
            **({"assign_goals": self.assign_goals} if self.assign_goals is not None else {}),
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
