"""Checks before any search: swarm size, and starts / goals that can never be valid.

``MAX_VEHICLES`` bounds the scenarios the prioritised planner accepts (a user mistake beyond it,
exit 2, instead of hours of planning). Every start must be valid at t = 0 against the other
vehicles' starts, and every goal (a vehicle holds it forever) against the other goals, with the
same constraints the planner uses (separation, downwash cut-offs both ways, keep-out ellipsoid,
workspace, obstacles); the first violation becomes an :class:`InfeasibleError` naming the vehicle
and the constraint, found in one vectorised check per vehicle.
"""

from __future__ import annotations

import numpy as np

from proxplan.fileio import UserError
from proxplan.planfile import Scenario
from proxplan.planner.constraints import Track, build_checker
from proxplan.planner.errors import InfeasibleError
from proxplan.planner.validity import BatchChecker

MAX_VEHICLES = 1000  # largest swarm the prioritised planner accepts


def check_swarm_size(scenario: Scenario) -> None:
    """UserError when the scenario has no vehicle or more than ``MAX_VEHICLES``."""
    n = len(scenario.vehicles)
    where = f"{scenario.source_path}: " if scenario.source_path else ""
    if n == 0:
        raise UserError(f"{where}vehicles: expected at least one vehicle, got none")
    if n > MAX_VEHICLES:
        raise UserError(
            f"{where}vehicles: expected at most {MAX_VEHICLES} vehicles for the prioritised planner, got {n} "
            "(split the swarm into groups)"
        )


def check_starts_and_goals(scenario: Scenario, *, mode: str) -> None:
    """InfeasibleError for the first start (at t = 0) or goal (held forever) that is invalid; a goal
    is checked for the moving vehicle that ends there (against the others' final positions)."""
    names = list(scenario.vehicles)
    for kind in ("start", "goal"):
        points = {}
        for n in names:
            task = scenario.vehicles[n]
            if kind == "start" or task.hover:
                points[n] = task.start_m
            elif task.goal_m is not None:
                points[n] = task.goal_m
        for name in names:
            task = scenario.vehicles[name]
            if name not in points or (kind == "goal" and (task.dock_with is not None or task.hover)):
                continue  # a goal conflict is the moving vehicle's, named as such
            others = [Track.static(o, scenario.vehicles[o].vehicle, p) for o, p in points.items() if o != name]
            # a dock pair meets on purpose: the dock target is exempt for the docking vehicle
            dock = scenario.vehicles[name].dock_with
            others = [tr for tr in others if tr.name != dock and scenario.vehicles[tr.name].dock_with != name]
            # starts and goals are held at rest: no tracking tube (as the verifier for resting pairs)
            batch = BatchChecker.from_checker(build_checker(scenario, name, others, mode=mode, tube=False))
            _, bad = batch.first_conflict(np.asarray(points[name], dtype=float)[None, :], np.zeros(1))
            if bad is not None and bad != "workspace" and not bad.startswith("obstacle"):  # those: pipeline
                where = "at t = 0" if kind == "start" else "while holding it"
                raise InfeasibleError(
                    name,
                    bad,
                    f"vehicle {name!r}: its {kind} {np.round(points[name], 4).tolist()} violates '{bad}' {where}",
                )
