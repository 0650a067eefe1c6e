"""What the review app shows, loaded from a plan.json or planned from a scenario YAML.

Frames: world z up, positions in m, times in s. Every vehicle of a plan shares one time grid
(DESIGN.md section 4). Reading, validation and planning are the planner's (``proxplan.planfile.plan.read_plan``,
``proxplan.planfile.scenario``, ``proxplan.planner.pipeline.plan_scenario``); this module only reshapes the result.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from proxplan.fileio import UserError
from proxplan.physics import Vehicle
from proxplan.planfile import VehicleTrajectory

Progress = Callable[[str, float], None]


@dataclass(frozen=True)
class ReviewVehicle:
    """One vehicle's planned trajectory (``trajectory``, the plan file's) and its task."""

    trajectory: VehicleTrajectory
    goal_m: np.ndarray | None = None  # (3,) world goal, m, when the scenario gives one
    dock_with: str | None = None  # name of the vehicle this one docks with
    dock_offset_m: np.ndarray | None = None  # (3,) goal relative to dock_with, m

    @property
    def name(self) -> str:
        return self.trajectory.name

    @property
    def type_name(self) -> str:
        return self.trajectory.type_name

    @property
    def vehicle(self) -> Vehicle:
        return self.trajectory.vehicle

    @property
    def t_s(self) -> np.ndarray:
        """Plan time grid (N,), s."""
        return self.trajectory.t_s

    @property
    def position_m(self) -> np.ndarray:
        """Planned positions (N, 3), world frame, m."""
        return self.trajectory.position_m

    def position_at(self, t_s: float) -> np.ndarray:
        """Position (3,) at time ``t_s`` from the plan-file sampler, m."""
        return self.trajectory.position_at(t_s)[0]


@dataclass(frozen=True)
class ReviewData:
    """Everything drawn: workspace box (m), obstacles (K, 2, 3) as (min, max) corners, vehicles."""

    name: str
    workspace_min_m: np.ndarray  # (3,)
    workspace_max_m: np.ndarray  # (3,)
    obstacles_m: np.ndarray  # (K, 2, 3)
    vehicles: dict[str, ReviewVehicle]
    authority_fraction: float = 0.5  # limits.authority_fraction, -
    metrics: dict[str, Any] = field(default_factory=dict)
    source_path: Path | None = None
    scenario: Any = None  # proxplan.planfile.scenario.Scenario, None when the plan carries none
    plan: Any = None  # proxplan.planfile.plan.Plan
    note: str = ""  # what the user should know (e.g. why editing is disabled)

    @property
    def t_start_s(self) -> float:
        return min(float(v.t_s[0]) for v in self.vehicles.values())

    @property
    def t_end_s(self) -> float:
        return max(float(v.t_s[-1]) for v in self.vehicles.values())

    def positions_at(self, t_s: float) -> dict[str, np.ndarray]:
        """Each vehicle's position (3,) at ``t_s``, m."""
        return {name: v.position_at(t_s) for name, v in self.vehicles.items()}


def _scenario_of_plan(plan: Any, path: Path) -> tuple[Any, str]:
    """The planner Scenario a plan was made for (``proxplan.verify.checks.scenario_of_plan``) and a note;
    (None, why) when it carries none or it does not load."""
    from proxplan.verify import scenario_of_plan

    try:
        return scenario_of_plan(plan, label=str(path)), ""
    except UserError as err:
        return None, f"scenario not loaded ({err}); showing the trajectories alone (no disturbance, no editing)"


def _fallback_bounds(position_m: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    pts = np.concatenate(position_m)
    lo, hi = pts.min(axis=0) - 0.5, pts.max(axis=0) + 0.5
    lo[2] = min(lo[2], 0.0)
    return lo, hi


def review_from_plan_result(plan: Any, scenario: Any, *, source_path: Path | None = None, note: str = "") -> ReviewData:
    """Review data of a ``Plan`` and its ``Scenario`` (or None: trajectories alone)."""
    vehicles: dict[str, ReviewVehicle] = {}
    for name, tr in plan.vehicles.items():
        task = scenario.vehicles.get(name) if scenario is not None else None
        if task is not None:
            extras = {
                "goal_m": None if task.goal_m is None else np.asarray(task.goal_m, float),
                "dock_with": task.dock_with,
                "dock_offset_m": None if task.dock_offset_m is None else np.asarray(task.dock_offset_m, float),
            }
        else:
            extras = {}
        vehicles[name] = ReviewVehicle(tr, **extras)
    if scenario is not None:
        lo = np.asarray(scenario.workspace_min_m, float)
        hi = np.asarray(scenario.workspace_max_m, float)
        boxes = np.array([(b.min_m, b.max_m) for b in scenario.obstacles], dtype=float).reshape(-1, 2, 3)
        fraction = float(scenario.limits.authority_fraction)
    else:
        lo, hi = _fallback_bounds([v.position_m for v in vehicles.values()])
        boxes = np.zeros((0, 2, 3))
        fraction = 0.5
    return ReviewData(
        name=scenario.name if scenario is not None else plan.scenario,
        workspace_min_m=lo,
        workspace_max_m=hi,
        obstacles_m=boxes,
        vehicles=vehicles,
        authority_fraction=fraction,
        metrics=dict(plan.metrics),
        source_path=source_path,
        scenario=scenario,
        plan=plan,
        note=note,
    )


def load_plan_file(path: str | Path) -> ReviewData:
    """Read a plan.json (or a directory holding one) for review; UserError on a bad file."""
    from proxplan.planfile import read_plan

    path = Path(path)
    if path.is_dir():
        path = path / "plan.json"
    plan = read_plan(path)
    scenario, note = _scenario_of_plan(plan, path)
    return review_from_plan_result(plan, scenario, source_path=path, note=note)


def plan_scenario(scenario: Any, *, progress: Progress | None = None, method: str = "optimized") -> Any:
    """Plan with ``proxplan.planner.pipeline.plan_scenario``; raises its InfeasibleError or UserError."""
    from proxplan.planner import plan_scenario as pipeline_plan

    return pipeline_plan(scenario, method=method, progress=progress)


def load_input(path: str | Path, *, progress: Progress | None = None) -> ReviewData:
    """A scenario YAML (planned now) or a plan.json / directory with one, as review data."""
    path = Path(path)
    if not path.exists():
        raise UserError(f"{path}: no such file; expected SCENARIO.yaml, DIR/plan.json or DIR")
    if path.suffix in (".yaml", ".yml"):
        from proxplan.planfile import load_scenario

        scenario = load_scenario(path)
        plan = plan_scenario(scenario, progress=progress)
        return review_from_plan_result(plan, scenario, source_path=path)
    return load_plan_file(path)
