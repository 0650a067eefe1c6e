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
"""

from __future__ import annotations

import numpy as np

from proxplan.fileio import UserError
from proxplan.planfile import MAX_VEHICLES, Scenario
from proxplan.planner.constraints import Track, build_checker
from proxplan.planner.errors import InfeasibleError
from proxplan.planner.validity import BatchChecker

__all__ = ["MAX_VEHICLES", "check_close_pairs", "check_starts_and_goals", "check_swarm_size"]


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
    from proxplan.planner.constraints import cutoff_table

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
