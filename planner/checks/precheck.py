"""Checks before any search: swarm size, and starts / goals that can never be valid.

``MAX_VEHICLES`` bounds the scenarios the planners accept (a user mistake beyond it, exit 2,
instead of hours of planning; the scenario loader rejects such a file before building its vehicles).
:func:`check_close_pairs` rejects (``UserError``, exit 2, naming both vehicles) starts or goals
closer than the pair's separation and a goal inside another goal's downwash cut-off, in one
``scipy.spatial.cKDTree`` pair query and vectorised table look-ups (10,000 vehicles in well under a
second). Every start must be valid at t = 0 against the other
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
from proxplan.planfile import MAX_VEHICLES, Scenario
from proxplan.planner.checks.constraints import Track, build_checker
from proxplan.planner.checks.validity import BatchChecker
from proxplan.planner.errors import InfeasibleError

GOAL_SEARCH_STEP_M = 0.005  # radius step of the nearest-clear-goal search, m
GOAL_SEARCH_MAX_M = 1.0  # largest goal displacement the search proposes, m
GOAL_SEARCH_DIRECTIONS = 256  # directions per sphere (Fibonacci lattice)
__all__ = [
    "MAX_VEHICLES",
    "check_close_pairs",
    "check_goal_tubes",
    "check_starts_and_goals",
    "check_swarm_size",
    "nearest_clear_goal",
]


def check_swarm_size(scenario: Scenario) -> None:
    """UserError when the scenario has no vehicle or more than ``MAX_VEHICLES``."""
    n = len(scenario.vehicles)
    where = f"{scenario.source_path}: " if scenario.source_path else ""
    if n == 0:
        raise UserError(f"{where}vehicles: expected at least one vehicle, got none")
    if n > MAX_VEHICLES:
        raise UserError(
            f"{where}vehicles: expected at most {MAX_VEHICLES} vehicles, got {n} (split the swarm into groups)"
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


def _final_points(scenario: Scenario) -> dict[str, np.ndarray]:
    """Where each non-docking vehicle ends (goal, or start for hovering ones), m."""
    out: dict[str, np.ndarray] = {}
    for n, task in scenario.vehicles.items():
        end = task.start_m if task.hover else task.goal_m
        if task.dock_with is None and end is not None:
            out[n] = end
    return out


def check_close_pairs(scenario: Scenario) -> None:
    """UserError (see module) for the first pair of starts / goals closer than their separation
    (max(limits.min_separation_m, sum of body radii), m) and the first goal inside the cut-off
    r_cut(dz) of a goal above it (both at rest: no tracking tube). Dock pairs are exempt."""
    from scipy.spatial import cKDTree

    from proxplan.costmaps import effects_key
    from proxplan.planner.checks.constraints import cutoff_table

    where = f"{scenario.source_path}: " if scenario.source_path else ""
    lim = scenario.limits
    names_all = list(scenario.vehicles)
    radius = {n: scenario.vehicles[n].vehicle.body_radius_m for n in names_all}
    r_max = max(radius.values())
    dock = {(n, t.dock_with) for n, t in scenario.vehicles.items() if t.dock_with is not None}

    def exempt(a: str, b: str) -> bool:
        return (a, b) in dock or (b, a) in dock

    for kind, points in (
        ("start", {n: t.start_m for n, t in scenario.vehicles.items()}),
        ("goal", _final_points(scenario)),
    ):
        names = list(points)
        if len(names) < 2:
            continue
        xyz = np.array([points[n] for n in names], dtype=float)
        tree = cKDTree(xyz)
        pairs = tree.query_pairs(max(lim.min_separation_m, 2.0 * r_max), output_type="ndarray")
        if pairs.size:
            i, j = pairs[:, 0], pairs[:, 1]
            d = np.linalg.norm(xyz[i] - xyz[j], axis=1)
            need = np.maximum(lim.min_separation_m, np.array([radius[names[a]] + radius[names[b]] for a, b in pairs]))
            bad = np.flatnonzero((d < need) & ~np.array([exempt(names[a], names[b]) for a, b in pairs]))
            if bad.size:
                k = bad[np.lexsort((j[bad], i[bad]))][0]
                a, b = names[i[k]], names[j[k]]
                raise UserError(
                    f"{where}vehicles.{a}.{kind} and vehicles.{b}.{kind}: {d[k]:.3f} m apart; expected at least "
                    f"{need[k]:.3f} m (limits.min_separation_m or the two body radii)"
                )
    goals = _final_points(scenario)
    names = list(goals)
    if len(names) < 2:
        return
    xyz = np.array([goals[n] for n in names], dtype=float)
    form, fx = scenario.field_form, effects_key(getattr(scenario, "effects", ()))
    tables = {}
    for a in {scenario.vehicles[n].vehicle for n in names}:
        for b in {scenario.vehicles[n].vehicle for n in names}:
            tables[(a, b)] = cutoff_table(
                a, b, level=lim.authority_fraction, rule=lim.invalid_zone_rule, field_form=form, effects=fx
            )
    reach = max(max(t.r_cut_m) for t in tables.values())
    if reach <= 0:
        return
    pairs = cKDTree(xyz[:, :2]).query_pairs(reach, output_type="ndarray")
    if pairs.size == 0:
        return
    # order each pair as (source above, target below)
    hi = np.where(xyz[pairs[:, 0], 2] >= xyz[pairs[:, 1], 2], pairs[:, 0], pairs[:, 1])
    lo = np.where(hi == pairs[:, 0], pairs[:, 1], pairs[:, 0])
    dz = xyz[hi, 2] - xyz[lo, 2]
    r = np.linalg.norm(xyz[hi, :2] - xyz[lo, :2], axis=1)
    rc = np.array(
        [
            tables[(scenario.vehicles[names[s]].vehicle, scenario.vehicles[names[t]].vehicle)].lookup(float(z))
            for s, t, z in zip(hi, lo, dz, strict=True)
        ]
    )
    bad = np.flatnonzero((r < rc) & ~np.array([exempt(names[s], names[t]) for s, t in zip(hi, lo, strict=True)]))
    if bad.size:
        k = bad[np.lexsort((hi[bad], lo[bad]))][0]
        t_name, s_name = names[lo[k]], names[hi[k]]
        raise UserError(
            f"{where}vehicles.{t_name}.goal is inside the downwash cut-off of vehicles.{s_name}.goal "
            f"({r[k]:.3f} m to the side, {dz[k]:.3f} m below; expected at least {rc[k]:.3f} m to the side at "
            f"authority level {lim.authority_fraction:g})"
        )
