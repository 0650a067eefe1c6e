"""Checks before any search: swarm size, and starts / goals that can never be valid.

``MAX_VEHICLES`` bounds the scenarios the prioritised planner accepts (a user mistake beyond it,
exit 2, instead of hours of planning). Every start must be valid at t = 0 against the other
vehicles' starts, and every goal (a vehicle holds it forever) against the other goals, with the
same constraints the planner uses (separation, downwash cut-offs both ways, keep-out ellipsoid,
workspace, obstacles); the first violation becomes an :class:`InfeasibleError` naming the vehicle
and the constraint, found in one vectorised check per vehicle.

A goal is reached *moving*: while a vehicle flies, the planner and the verifier grow every keep-out
(separation, downwash cut-off, invalid zone) by the tracking tube ``limits.tracking_margin_m``.
A goal that is valid at rest but inside such a grown keep-out cannot be approached at all;
:func:`check_goal_tubes` says so before any search, naming the vehicle, the source of the keep-out,
how far the goal lies inside it and the nearest goal clear of it (one vectorised check of candidate
points on spheres around the goal).
"""

from __future__ import annotations

import numpy as np

from proxplan.fileio import UserError
from proxplan.planfile import Scenario
from proxplan.planner.constraints import Track, build_checker
from proxplan.planner.errors import InfeasibleError
from proxplan.planner.validity import BatchChecker

MAX_VEHICLES = 1000  # largest swarm the prioritised planner accepts
GOAL_SEARCH_STEP_M = 0.005  # radius step of the nearest-clear-goal search, m
GOAL_SEARCH_MAX_M = 1.0  # largest goal displacement the search proposes, m
GOAL_SEARCH_DIRECTIONS = 256  # directions per sphere (Fibonacci lattice)


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


def _sphere_directions(k: int) -> np.ndarray:
    """(k, 3) unit vectors spread evenly over the sphere (Fibonacci lattice), deterministic."""
    i = np.arange(k) + 0.5
    z = 1.0 - 2.0 * i / k
    phi = np.pi * (1.0 + 5.0**0.5) * i
    r = np.sqrt(1.0 - z**2)
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), z])


def nearest_clear_goal(batch: BatchChecker, goal_m: np.ndarray) -> np.ndarray | None:
    """The point nearest to ``goal_m`` (3,) that ``batch`` finds valid (to ``GOAL_SEARCH_STEP_M``),
    searched on spheres of growing radius up to ``GOAL_SEARCH_MAX_M``; None if there is none."""
    dirs = _sphere_directions(GOAL_SEARCH_DIRECTIONS)
    radii = np.arange(1, int(round(GOAL_SEARCH_MAX_M / GOAL_SEARCH_STEP_M)) + 1) * GOAL_SEARCH_STEP_M
    pts = (goal_m[None, None, :] + radii[:, None, None] * dirs[None, :, :]).reshape(-1, 3)
    static, code = batch.conflict_codes(pts, np.zeros(len(pts)))
    ok = np.flatnonzero((static < 0) & (code < 0))
    return None if ok.size == 0 else pts[ok[0]]


def check_goal_tubes(scenario: Scenario, *, mode: str, margin_m: float = 0.0) -> None:
    """InfeasibleError for the first goal that is valid at rest but lies inside another vehicle's
    keep-out grown by the tracking tube (the vehicle arrives moving, so the tube applies), with
    ``details``: the other vehicle, the tube, how far the goal must move, the nearest clear goal.
    Keep-outs include ``margin_m`` (m), the margin the planner searches with (a goal inside it is
    one the search cannot reach)."""
    tube = float(scenario.limits.tracking_margin_m)
    if tube <= 0.0:
        return
    final = {n: scenario.final_position_m(n) for n in scenario.vehicles}
    for name, task in scenario.vehicles.items():
        if task.hover or task.dock_with is not None or task.goal_m is None:
            continue  # docks meet on purpose (exempt on their approach); hovering vehicles do not arrive
        others = [
            Track.static(o, scenario.vehicles[o].vehicle, p)
            for o, p in final.items()
            if o != name and scenario.vehicles[o].dock_with != name
        ]
        batch = BatchChecker.from_checker(
            build_checker(scenario, name, others, mode=mode, tube=True, margin_m=margin_m)
        )
        goal = np.asarray(task.goal_m, dtype=float)
        _, bad = batch.first_conflict(goal[None, :], np.zeros(1))
        if bad is None or bad == "workspace" or bad.startswith("obstacle"):
            continue
        other = bad.split(" ")[-1]
        clear = nearest_clear_goal(batch, goal)
        shift = None if clear is None else float(np.linalg.norm(clear - goal))
        where = f"{scenario.source_path}: vehicles.{name}.goal: " if scenario.source_path else ""
        suggestion = (
            f"the nearest goal clear of it is {np.round(clear, 3).tolist()} ({shift:.3f} m away)"
            if clear is not None
            else f"no goal within {GOAL_SEARCH_MAX_M:g} m is clear of it"
        )
        raise InfeasibleError(
            name,
            bad,
            f"{where}vehicle {name!r}: its goal {np.round(goal, 4).tolist()} is clear at rest but inside the "
            f"'{bad}' keep-out grown by the tracking tube (limits.tracking_margin_m = {tube:g} m"
            + (f", plus the planner's {margin_m:g} m search margin" if margin_m > 0 else "")
            + f"), which applies while it arrives; {suggestion}",
            details={
                "kind": "goal-in-tube",
                "vehicle": name,
                "other_vehicle": other,
                "constraint": bad,
                "tracking_margin_m": tube,
                "search_margin_m": margin_m,
                "goal_m": goal.tolist(),
                "shortfall_m": shift,
                "suggested_goal_m": None if clear is None else np.round(clear, 4).tolist(),
            },
        )
