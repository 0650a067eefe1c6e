"""Prioritised continuous planning as a stage of the swarm layer (:mod:`proxplan.planner.swarm.plan`,
stage 2), two ways, the shorter plan kept by the caller: the straight lines in no conflict kept and
only the other vehicles planned around them (:func:`kept_straight_stage`), and every vehicle in each
of ``SwarmOptions.orders`` (:data:`ORDERS`; :func:`prioritised_stage`; groups that never interact
apart, :mod:`proxplan.planner.swarm.components`), on a horizon of :func:`horizon_steps` and within a
count of single-vehicle plannings (:func:`prioritised_budget`). The planning of one pass is
:mod:`proxplan.planner.swarm.priority`.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from proxplan.planner.swarm.components import interaction_groups, plan_groups, subproblem
from proxplan.planner.swarm.fill_order import fill_order
from proxplan.planner.swarm.options import SwarmOptions
from proxplan.planner.swarm.priority import in_collision_cap, prioritized_tracks
from proxplan.planner.swarm.priority_options import PrioritizedFailed, PriorityOptions, PriorityResult
from proxplan.planner.swarm.priority_order import dependency_order
from proxplan.planner.swarm.problem import SwarmProblem
from proxplan.planner.swarm.raised import RAISE_DZ_M, a_level
from proxplan.planner.swarm.stage import Stage, own_routes
from proxplan.planner.swarm.straight import kept_straight_lines
from proxplan.planner.swarm.tracks import GRID_DT_S
from proxplan.planner.ties import LENGTH_RESOLUTION_M, tie_key

# prioritised planning's horizon: max(factor x lower bound, lower bound + margin) (a plan that needs
# longer is not worth having: the lattice plan in lock-step is the answer then)
PRIORITISED_HORIZON_FACTOR = 4.0
PRIORITISED_HORIZON_MARGIN_S = 20.0


__all__ = [
    "FAR_GOALS_FIRST",
    "ORDERS",
    "PRIORITISED_HORIZON_FACTOR",
    "PRIORITISED_HORIZON_MARGIN_S",
    "horizon_steps",
    "kept_straight_stage",
    "longest_first",
    "prioritised_budget",
    "prioritised_stage",
    "raised_arm",
]


def longest_first(problem: SwarmProblem) -> list[int]:
    """Planning order: the longer straight line first (it sets the makespan), ties by index."""
    length = np.linalg.norm(problem.goals_m - problem.starts_m, axis=1)
    return sorted(range(problem.n_agents), key=lambda a: (-tie_key(float(length[a]), LENGTH_RESOLUTION_M), a))


# the goal block filled from its far side (swarm.fill_order): the stacked plan's levels are planned in it
# beside their first order (plan._level_options; round 24B)
FAR_GOALS_FIRST = "far goals first"

ORDERS: dict[str, Callable[[SwarmProblem], list[int]]] = {
    "dependencies first": dependency_order,
    "longest first": longest_first,
    FAR_GOALS_FIRST: fill_order,
}


def prioritised_budget(problem: SwarmProblem, opts: SwarmOptions) -> int:
    """Single-vehicle plannings of prioritised planning over all its passes (``opts.plannings_per_vehicle``
    per vehicle; the pass with both wavefronts, ``SwarmOptions.heights``, spends what is left)."""
    return math.ceil(opts.plannings_per_vehicle * problem.n_agents)


def horizon_steps(lower_bound_s: float) -> int:
    """Prioritised planning's horizon in grid steps (``GRID_DT_S``) for a plan whose lower bound is
    ``lower_bound_s`` (s)."""
    horizon_s = max(PRIORITISED_HORIZON_FACTOR * lower_bound_s, lower_bound_s + PRIORITISED_HORIZON_MARGIN_S)
    return int(round(horizon_s / GRID_DT_S))


def kept_straight_stage(
    problem: SwarmProblem, lower_bound_s: float, opts: SwarmOptions, extra: dict, *, progress, deadline
) -> Stage | None:
    """Straight lines where they conflict with nobody, prioritised planning with repair for the
    rest (:func:`~proxplan.planner.swarm.straight.kept_straight_lines`); None when it gives up or
    keeps no line (then it is prioritised planning of everyone)."""
    if not opts.keep_straight:
        return None
    horizon = horizon_steps(lower_bound_s)
    t1 = time.perf_counter()
    kept, conflicted = kept_straight_lines(problem, horizon)
    if not kept:
        extra["kept_straight"] = "no straight line conflicts with nobody"
        return None
    order = [a for a in dependency_order(problem) if a in conflicted]
    options = PriorityOptions(
        max_repairs=math.ceil(opts.repairs_per_vehicle * problem.n_agents),
        hold_s=opts.unplanned_hold_s[0],
        reserve_starts=opts.reserve_starts is not False,
        through=opts.through_waypoints == "always",
    )
    try:
        result = prioritized_tracks(
            problem, order, options, horizon_steps=horizon, initial=kept, progress=progress, deadline=deadline
        )
    except PrioritizedFailed as err:
        extra["kept_straight"] = f"{len(kept)} kept, {len(conflicted)} planned: gave up ({'; '.join(err.history[-2:])})"
        extra["kept_straight_time_s"] = round(time.perf_counter() - t1, 3)
        return None
    still = sum(1 for a, tr in kept.items() if result.tracks.get(a) is tr)
    extra["kept_straight"] = f"{len(kept)} kept ({still} after repairs), {len(conflicted)} planned"
    extra["kept_straight_time_s"] = round(time.perf_counter() - t1, 3)
    coordination = (
        f"straight lines of {still} vehicles in no conflict kept, the other {problem.n_agents - still} planned "
        f"around them ({result.planned} vehicle plannings, {result.repairs} repairs, {result.against_order} against the order)"
    )
    tracks = [result.tracks[a] for a in range(problem.n_agents)]
    return Stage(tracks, "prioritised", coordination, own_routes(problem, tracks))


def prioritised_stage(
    problem: SwarmProblem,
    lower_bound_s: float,
    opts: SwarmOptions,
    extra: dict,
    *,
    progress,
    deadline,
    heights: bool = False,
    only: tuple[str, float] | None = None,
    budget: int | None = None,
) -> Stage | None:
    """Prioritised continuous planning of each group of vehicles that interact, in each of
    ``opts.orders``, the shorter plan kept; each order with the first of ``opts.unplanned_hold_s``
    for which it finds a plan; all within a count of single-vehicle plannings
    (``opts.plannings_per_vehicle``); None when every one gives up. With one group, a pass whose
    plannings left cannot plan the vehicles it still has queued gives up at once and is charged
    the whole budget left (``PriorityOptions.give_up_early``): it would spend it and give up all the
    same, so the same passes run after it and the plan is the same (``counts["planned"]`` counts
    the plannings made; ``counts["charged"]`` those charged). ``only``: the one (order label, hold)
    to run; ``budget``: the plannings of the whole stage (default ``opts.plannings_per_vehicle`` per
    vehicle).

    On a top or bottom level of the stacked plan with room above its vehicles (:func:`raised_arm`), these
    passes are planned flat (the *flat arm*), then again with routes raised over the others
    (:mod:`~proxplan.planner.swarm.raised`; the *raised arm*, ``opts.raised_routes``), within
    ``opts.raised_plannings_per_vehicle`` plannings per vehicle, unless the flat arm's plan already
    arrives at ``lower_bound_s`` (nothing is earlier); the shorter plan of the two kept, ties the flat
    arm's: never longer than the flat arm (round 30A: a greedy earlier arrival per vehicle made family
    random-0's level longer)."""
    t1 = time.perf_counter()
    flat = _passes(problem, lower_bound_s, opts, progress, deadline, heights, only, budget, raised=False)
    best, tried, counts = flat
    if raised_arm(problem, opts):
        bound_steps = int(round(lower_bound_s / GRID_DT_S))
        if best is not None and _makespan_steps(best) <= bound_steps:
            tried.append("routes raised: not tried (the flat plan arrives at the bound)")
        else:
            raised_budget = math.ceil(opts.raised_plannings_per_vehicle * problem.n_agents)
            if budget is not None:
                raised_budget = min(raised_budget, budget)
            up, up_tried, up_counts = _passes(
                problem, lower_bound_s, opts, progress, deadline, heights, only, raised_budget, raised=True
            )
            tried.extend(f"routes raised, {t}" for t in up_tried)
            for key in ("planned", "repairs", "against_order", "charged"):
                counts[key] += up_counts[key]
            counts["raised_planned"] = up_counts["planned"]
            if up is not None and (best is None or _makespan_steps(up) < _makespan_steps(best)):
                best = replace(
                    up,
                    coordination=up.coordination.replace(
                        "prioritised continuous planning", "prioritised continuous planning, routes raised", 1
                    ),
                )
    extra["prioritised"] = "; ".join(tried)
    extra["prioritised_time_s"] = round(time.perf_counter() - t1, 3)
    extra["counts"] = counts
    return best


def _makespan_steps(stage: Stage) -> int:
    return max(tr.arrival_step for tr in stage.tracks)


def raised_arm(problem: SwarmProblem, opts: SwarmOptions) -> bool:
    """Whether :func:`prioritised_stage` plans ``problem`` a second time with routes raised: ``opts.raised_routes``,
    a top or bottom level of the stacked plan (:func:`~proxplan.planner.swarm.raised.a_level`) and room
    above its vehicles for the least raise (:data:`~proxplan.planner.swarm.raised.RAISE_DZ_M`; a bottom
    level's vehicles sit at its band's top: no raised route there, round 30A)."""
    if not (opts.raised_routes and a_level(problem)):
        return False
    top = max(float(problem.starts_m[:, 2].max()), float(problem.goals_m[:, 2].max()))
    return top + min(RAISE_DZ_M) <= float(problem.hi_m[2])


def _passes(
    problem: SwarmProblem,
    lower_bound_s: float,
    opts: SwarmOptions,
    progress,
    deadline,
    heights: bool,
    only: tuple[str, float] | None,
    budget: int | None,
    *,
    raised: bool,
) -> tuple[Stage | None, list[str], dict]:
    """The passes of :func:`prioritised_stage` (see there), routes raised or not: (the shortest plan or
    None, what each pass did, the counts)."""
    horizon = horizon_steps(lower_bound_s)
    groups = interaction_groups(problem)
    workers = opts.workers if opts.workers > 0 else (os.cpu_count() or 1)
    tried = []
    best: Stage | None = None
    counts = {"groups": len(groups), "planned": 0, "repairs": 0, "against_order": 0}
    if budget is None:
        budget = prioritised_budget(problem, opts)
    charged = 0  # plannings charged to the budget: those made, or a pass's whole budget when it gave up early
    # (every group's order, hold) -> (order label, its result or None when it gave up, its plannings)
    ran: dict[tuple, tuple[str, PriorityResult | None, int]] = {}
    for label in opts.orders if only is None else (only[0],):
        orders = tuple(tuple(ORDERS[label](subproblem(problem, g) if len(groups) > 1 else problem)) for g in groups)
        for hold_s in opts.unplanned_hold_s if only is None else (only[1],):
            left = budget - charged
            same = ran.get((orders, hold_s))
            if same is not None:
                # a pass is a function of its orders and options: run again on what is left of the
                # budget it plans the same vehicles in the same sequence and gives the same plan, or
                # gives up on the budget (the plannings charged are then those of the budget left)
                first, got, spent = same
                tried.append(f"{label}, hold {hold_s:g} s: the same orders as {first}, not run again")
                counts["planned"] += min(spent, max(0, left))
                charged += min(spent, max(0, left))
                if got is not None and spent <= left:
                    counts["repairs"] += got.repairs
                    counts["against_order"] += got.against_order
                    break
                continue
            ran[(orders, hold_s)] = (label, None, 0)
            if left <= 0:
                tried.append(f"{label}, hold {hold_s:g} s: not tried (planning budget of {budget} spent)")
                continue
            options = PriorityOptions(
                max_repairs=math.ceil(opts.repairs_per_vehicle * max(len(g) for g in groups)),
                max_plannings=left,
                hold_s=hold_s,
                reserve_starts=opts.reserve_starts is not False,
                through=opts.through_waypoints == "always",
                heights=heights,
                # one group is given the whole budget left: a pass that could not finish within it
                # leaves nothing for the next either way (with several, each has its share, and what
                # a failing group would have spent past its share is not known)
                give_up_early=len(groups) == 1,
                max_in_collision=in_collision_cap(max(len(g) for g in groups)),
                raised=raised,
            )
            try:
                result = plan_groups(
                    problem,
                    groups,
                    ORDERS[label],
                    options,
                    horizon_steps=horizon,
                    workers=workers,
                    progress=progress,
                    deadline=deadline,
                )
            except PrioritizedFailed as err:
                ran[(orders, hold_s)] = (label, None, err.charged)
                counts["planned"] += err.planned
                charged += err.charged
                tried.append(
                    f"{label}, hold {hold_s:g} s: gave up after {err.planned} plannings ("
                    + "; ".join(err.history[-2:])
                    + ")"
                )
                continue
            ran[(orders, hold_s)] = (label, result, result.planned)
            counts["planned"] += result.planned
            charged += result.planned
            counts["repairs"] += result.repairs
            counts["against_order"] += result.against_order
            makespan = max(tr.arrival_s for tr in result.tracks.values())
            tried.append(f"{label}, hold {hold_s:g} s: {makespan:.2f} s ({result.planned} plannings)")
            if best is None or makespan < max(tr.arrival_s for tr in best.tracks):
                tracks = [result.tracks[a] for a in range(problem.n_agents)]
                best = Stage(
                    tracks,
                    "prioritised",
                    f"prioritised continuous planning{', both wavefronts' if heights else ''}, {label}, vehicles not planned yet assumed to leave after "
                    f"{hold_s:g} s ({len(groups)} group(s), {result.planned} vehicle plannings, {result.repairs} "
                    f"repairs, {result.against_order} against the order)",
                    own_routes(problem, tracks),
                    pass_key=(label, hold_s),
                )
            break  # a longer hold only where this one found nothing
    counts["charged"] = charged
    return best, tried, counts
