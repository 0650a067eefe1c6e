"""``assign_goals: by_type`` applied to a scenario: the scenario with every interchangeable vehicle
given its assigned goal (:func:`proxplan.planner.swarm.assign.assign_by_type`), and the record of
the assignment for plan.json.

Interchangeable are the vehicles with a goal of their own; hovering and docking vehicles keep their
tasks (their "goal" is not a place others could take) and the record says so. Two vehicles of one
type listing the same goal is a user mistake (exit 2): one of them would have nowhere to go.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from proxplan.fileio import UserError
from proxplan.planfile import Scenario
from proxplan.planner.swarm.assign import assign_by_type
from proxplan.planner.swarm.obstacle_costs import pair_bounds_s


def apply_assignment(scenario: Scenario) -> tuple[Scenario, dict | None]:
    """(scenario with assigned goals, record) under ``assign_goals: by_type``; (scenario, None)
    otherwise. The record: ``goal_of`` {vehicle: the vehicle whose listed goal it takes},
    ``lower_bound_s`` (largest single-vehicle minimum time under the assignment), ``fixed``
    (vehicles kept as they are, with why)."""
    if scenario.assign_goals is None:
        return scenario, None
    label = scenario.source_path or "scenario"
    movers = [n for n, t in scenario.vehicles.items() if t.goal_m is not None and t.dock_with is None and not t.hover]
    fixed = {
        n: ("hovers" if t.hover else f"docks with {t.dock_with}")
        for n, t in scenario.vehicles.items()
        if n not in movers
    }
    by_goal: dict[tuple, str] = {}
    for n in movers:
        t = scenario.vehicles[n]
        assert t.goal_m is not None
        key = (t.type_name, tuple(np.round(t.goal_m, 6).tolist()))
        if key in by_goal:
            raise UserError(
                f"{label}: vehicles.{by_goal[key]}.goal and vehicles.{n}.goal: the same goal for two "
                f"'{t.type_name}' vehicles under assign_goals: by_type; expected a distinct goal per vehicle"
            )
        by_goal[key] = n
    if not movers:
        return scenario, {"goal_of": {}, "lower_bound_s": 0.0, "fixed": fixed}
    tasks = [scenario.vehicles[n] for n in movers]
    result = assign_by_type(
        np.array([t.start_m for t in tasks]),
        np.array([t.goal_m for t in tasks]),
        [t.type_name for t in tasks],
        [t.kinematic_limits for t in tasks],
        pair_bounds_s(scenario, movers) if scenario.obstacles else None,
    )
    vehicles = dict(scenario.vehicles)
    goal_of = {}
    for i, n in enumerate(movers):
        src = movers[int(result.goal_of[i])]
        goal_of[n] = src
        vehicles[n] = replace(scenario.vehicles[n], goal_m=np.array(scenario.vehicles[src].goal_m, dtype=float))
    record = {"goal_of": goal_of, "lower_bound_s": float(result.lower_bound_s), "fixed": fixed}
    return replace(scenario, vehicles=vehicles), record
