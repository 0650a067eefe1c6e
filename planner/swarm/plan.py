"""Swarm planning (``--method swarm``; ``optimized`` for swarms of ``SWARM_MIN_VEHICLES`` or
more): coordinate jointly on a lattice, fly in continuous time. One function per stage:

1. *Straight first* (:func:`_straight_stage`, :mod:`proxplan.planner.swarm.straight`): if every
   vehicle can fly its straight line at once, synchronised (one step, checked exactly pair by pair),
   that is the plan (the CAPT case of interchangeable goals).
2. *Continuous time, prioritised* (:mod:`proxplan.planner.swarm.priority`), two ways, the shorter
   plan kept: the straight lines in no conflict kept and only the other vehicles planned around
   them (:func:`_kept_straight_stage`), and every vehicle in each of ``SwarmOptions.orders``
   (:func:`_prioritised_stage`; groups that never interact apart,
   :mod:`proxplan.planner.swarm.components`). One vehicle after another along the best of its
   straight line and a wavefront route through the others' space-time, timed exactly; vehicles
   not planned yet are predictions; a vehicle that cannot be planned is repaired (only the vehicles
   in conflict with it planned again, after it), within a count of repairs per pass; one still
   failing then flies in collision and the collisions are repaired at the end of the pass
   (:mod:`proxplan.planner.swarm.lns`). With ``SwarmOptions.heights`` (on with fixed goals up to
   ``HEIGHTS_MAX_VEHICLES``), once
   the prioritised plan is re-timed (4), one more pass runs, in its order and hold,
   with both wavefronts per vehicle (the earlier arrival kept), on what is left of the count budget;
   it is re-timed too and replaces that plan only when it is shorter (:func:`_heights_way`): a
   vehicle's earlier arrival can lengthen the whole plan. None where prioritised planning gave up.
3. *Joint coordination*, when prioritised planning gives up (:func:`_lattice_stage`): LaCAM with
   PIBT on the lattice of the levels in use, long straight moves, synchronous conflicts checked
   exactly (:mod:`proxplan.planner.swarm.lacam`, a count of configurations bounds it), flown in
   lock-step (:mod:`proxplan.planner.swarm.lockstep`): conflict-free by construction, the
   guaranteed answer.
4. *Re-timing* (:func:`_retime_stage`): Gauss-Seidel passes (:mod:`proxplan.planner.swarm.retime`),
   every vehicle against the others' tracks in a space-time neighbourhood; never worse, always
   conflict-free.
5. *Makespan repair* (:func:`_makespan_stage`, :mod:`proxplan.planner.swarm.makespan`), once, on the
   plan kept: the latest vehicle planned again together with the vehicles in its way, while that
   shortens the plan, within a count of plannings; never worse, always conflict-free. Not on the
   lattice plan (``SwarmOptions.makespan_repair``).

The caller (the pipeline) runs the independent verifier on the result as on every plan. The
:class:`~proxplan.planner.swarm.info.SwarmInfo` names the ``stage`` that produced the tracks
("straight", "prioritised" or "lattice"), the lower bound (largest straight-line rest-to-rest time
of any vehicle) and the makespans after each stage.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from proxplan.planfile import Scenario
from proxplan.planner.sampling.ordering import lower_bound_makespan_s
from proxplan.planner.swarm.components import interaction_groups, plan_groups, subproblem
from proxplan.planner.swarm.info import LatticeInfo, MakespanRepairInfo, RetimeInfo, SwarmInfo, SwarmStage
from proxplan.planner.swarm.lacam import Lacam
from proxplan.planner.swarm.lattice import Lattice, build_lattice
from proxplan.planner.swarm.lockstep import lockstep_tracks
from proxplan.planner.swarm.makespan import budget as makespan_budget
from proxplan.planner.swarm.makespan import shorten_makespan
from proxplan.planner.swarm.occupancy import Occupancy, track_digest
from proxplan.planner.swarm.priority import (
    PrioritizedFailed,
    PriorityOptions,
    PriorityResult,
    dependency_order,
    prioritized_tracks,
)
from proxplan.planner.swarm.problem import SwarmProblem, swarm_applicable, swarm_problem
from proxplan.planner.swarm.retime import improve, route_chain
from proxplan.planner.swarm.straight import kept_straight_lines, straight_step_conflicts, straight_tracks
from proxplan.planner.swarm.sync import SyncTable
from proxplan.planner.swarm.tracks import GRID_DT_S, GridTrack
from proxplan.planner.timing.paths import TimedPath

SWARM_MIN_VEHICLES = 16  # formation changes with at least this many vehicles use the swarm layer by default
HORIZON_MARGIN_S = 5.0  # the re-timing horizon extends this far past the initial makespan, s
# prioritised planning's horizon: max(factor x lower bound, lower bound + margin) (a plan that needs
# longer is not worth having: the lattice plan in lock-step is the answer then)
PRIORITISED_HORIZON_FACTOR = 4.0
PRIORITISED_HORIZON_MARGIN_S = 20.0
# SwarmOptions.heights None is on with fixed goals for at most this many vehicles: its pass costs about
# two plain passes (two wavefronts per planning), more where the wavefront spreads over long horizons.
# Whole processes, main / with it, one run each (docs/planner.md, round 12B; loaded): circle-128 30.5 ->
# 59.2 s of CPU (issue 37's 128 target is 60 s), circle-256 172 s -> past 362 s (target 300 s); at 64
# the 30 s target holds (pillar 14.7 -> 25.2 s, circle 8.8 -> 14.7 s). Set watching those named
# layouts, not the family: the largest size of the bench at which the time targets still hold
HEIGHTS_MAX_VEHICLES = 64

__all__ = ["HEIGHTS_MAX_VEHICLES", "SWARM_MIN_VEHICLES", "SwarmOptions", "swarm_applicable", "swarm_timed"]


@dataclass(frozen=True)
class SwarmOptions:
    """Knobs of the swarm layer; every budget is a count (same plan on every machine)."""

    max_run: int = 4  # longest straight move of one coordination step, in lattice edges
    max_nodes: int = 3000  # LaCAM configurations before the coordination search gives up
    # LaCAM's PIBT proposals before it gives up (most fail or revisit a configuration and add none);
    # set on the named layouts at 64 fixed: grid 60, corridor 2378 to a plan; pillar none in 5800 (before
    # round 12A, when most PIBT proposals failed; now one without a constraint never does, swarm.lacam)
    max_proposals: int = 4000
    # prioritised planning's budget: single-vehicle plannings over all its passes (orders, holds,
    # repairs), per vehicle; once spent the best plan found so far is kept, or the lattice plan
    # is the answer (a count: the same plan on every machine). Set on the named layouts at 64
    # fixed (docs/planner.md): two orders need 2, a failing pass 1-3, a pass with repairs 2-3
    plannings_per_vehicle: float = 6.0
    passes: int = 3  # continuous re-timing passes
    prioritized: bool = True  # try prioritised continuous planning before the lattice coordination
    # prioritised planning's repair budget, per vehicle of a group (rounded up): on the named layouts at
    # 32 vehicles the plans that repaired at all needed 1-3 repairs; 2 per vehicle let grid-64 run
    # for minutes on failing passes
    repairs_per_vehicle: float = 0.25
    orders: tuple[str, ...] = ("dependencies first", "longest first")  # prioritised planning's orders (ORDERS)
    # a vehicle not planned yet is assumed to hold its start this long, then to leave on its straight
    # route, s: tried in turn until prioritised planning finds a plan (a longer hold leaves it more
    # room). No hold (0.0) was measured first and lost on grid and pillar layouts (see docs/planner.md)
    unplanned_hold_s: tuple[float, ...] = (1.0, 2.5)
    # a vehicle not planned yet holds its start until it is planned (swarm.reserve), instead of the
    # prediction above; the hold then applies to the starts released for a vehicle in their way. None: on
    # with fixed goals, off where the goals were assigned (assign_goals: by_type, decided by
    # planner.pipeline). With fixed goals at 64 the predictions start-trapped every
    # pass on grid and pillar (sixth round); reserved starts gave pillar-64 and random-1 plans where there
    # were none (seventh round). By type they made grid-64 1.63x -> 1.84x and corridor-64 2.23x -> 3.88x
    # (an assignment rarely puts a goal on another's start; docs/planner.md, seventh round; a default set
    # watching those named layouts). Called directly (not through the pipeline), None means on.
    reserve_starts: bool | None = None
    # fly through waypoints without stopping (else rest to rest at each): "retime" in the re-timing
    # passes only (each vehicle along its own route, against everyone's final tracks: never worse),
    # "always" in prioritised planning too, "never". Off by default: on the named layouts it did not
    # shorten the makespan for its CPU time (docs/planner.md, "Causes measured one at a time")
    through_waypoints: Literal["never", "retime", "always"] = "never"
    # also try: keep the straight lines in no conflict and plan only the others around them. Off by
    # default: on the named layouts at 32 vehicles it never gave the shorter plan (docs/planner.md)
    keep_straight: bool = False
    # after re-timing, once on the plan kept, plan the latest vehicles again together with the vehicles
    # in their way (swarm.makespan; False: for measuring the cause alone; True: on every plan). None:
    # on, but not on the lattice plan. Set watching the named layouts at 64 (docs/planner.md, round
    # 13A): on the prioritised plans with fixed goals pillar 2.73x -> 2.62x for 57 plannings, circle
    # unchanged (13); on the lattice plans nothing shorter: grid and corridor fixed (in-process, 64
    # plannings: 0 and 1 neighbourhoods replaced, the makespan unchanged, 5 and 22 s of CPU) and pillar
    # by type (62 plannings, none replaced, 7 s): the vehicles in the latest one's way cannot be planned
    # again among the lock-step tracks. On the prioritised plans by type it was on before (grid-64
    # 1.91x -> 1.63x, fifth round) and stays so. Decided by the swarm layer (no caller sets it)
    makespan_repair: bool | None = None
    # one more pass of prioritised planning with both wavefronts per vehicle (the widest disc at every
    # height and discs for the heights the route flies at, swarm.wave; the earlier arrival kept,
    # priority.plan_one), in the order and hold of the pass that gave the plan without, on what is left
    # of prioritised planning's count budget; the shorter of the two whole plans kept (each re-timed and
    # repaired; ties: the plan without), so never longer than without. No pass where prioritised
    # planning gave up (its budget spent: the lattice plan). None: on with fixed goals for up to
    # HEIGHTS_MAX_VEHICLES vehicles, off where the goals were assigned (Scenario.assign_goals: by_type).
    # Set watching the named layouts only (docs/planner.md, round 12B): fixed goals at 64, pillar 3.17x
    # -> 2.73x and circle 1.56x -> 1.51x for about +10 / +6 s of CPU, grid and corridor no pass (both
    # gave up); by type at 64 it shortened no named layout for +1.4 to +16.5 s of CPU (round 11S)
    heights: bool | None = None
    workers: int = 0  # Dask workers for groups that never interact (0: one per core; 1: none)
    # grow every vehicle's keep-outs by the bound on its predicted tracking error in any plan this
    # layer can time (swarm.tracking_bound), so that the verifier does not reject the first plan
    # by millimetres (False: only by ``deflection_m``, as before; for measuring the cause alone)
    tracking_bound: bool = True
    seed: int = 0
    # per vehicle name: its predicted deflection under the plan's own disturbance, m; a pair's
    # keep-out grows by the sum of its two vehicles' values (as in the verifier)
    deflection_m: Mapping[str, float] = field(default_factory=dict)


@dataclass
class _Stage:
    """Tracks of every agent (by agent index) from one stage, and what the stage reports."""

    tracks: list[GridTrack]
    stage: SwarmStage
    coordination: str
    routes: Callable[[int], list[np.ndarray]]  # the stage's own waypoint chain of an agent (re-timing)
    # prioritised planning's pass that gave the tracks: (order label, hold s); None for the other stages
    pass_key: tuple[str, float] | None = None


def swarm_timed(
    scenario: Scenario,
    options: SwarmOptions | None = None,
    *,
    progress: Callable[[str, float], None] | None = None,
    deadline: float | None = None,
) -> tuple[dict[str, TimedPath], SwarmInfo]:
    """Timed paths of every vehicle and the :class:`SwarmInfo` (see module);
    :class:`~proxplan.planner.errors.PlanNotFound` when the coordination search stops on its budget
    or the ``deadline`` (time.perf_counter() value)."""
    opts = options or SwarmOptions()
    why = swarm_applicable(scenario)
    if why is not None:
        raise ValueError(f"the swarm layer cannot plan this scenario: {why}")
    t0 = time.perf_counter()
    problem = swarm_problem(scenario, deflection_m=opts.deflection_m, tracking_bound=opts.tracking_bound)
    lower_bound = lower_bound_makespan_s(scenario)
    conflicts = straight_step_conflicts(problem)
    extra: dict = {}
    found = _straight_stage(problem) if not conflicts else None
    straight = found is not None
    if found is None and opts.prioritized:
        kept = _kept_straight_stage(problem, lower_bound, opts, extra, progress=progress, deadline=deadline)
        found = _prioritised_stage(problem, lower_bound, opts, extra, progress=progress, deadline=deadline)
        if kept is not None and (found is None or _makespan(kept) < _makespan(found)):
            found = kept
    if found is None:
        if progress:
            progress(f"coordination: lattice ({len(conflicts)} straight-line conflicts)", 0.05)
        found = _lattice_stage(problem, opts, extra, progress=progress, deadline=deadline)
        if opts.prioritized:  # say why: prioritised planning gave up within its count budget
            spent = extra.get("counts", {}).get("planned", 0)
            found.coordination = f"prioritised planning gave up ({spent} vehicle plannings); " + found.coordination
    initial = max(tr.arrival_s for tr in found.tracks)
    by_agent, retiming = _retime_stage(problem, found, initial, opts, progress=progress, deadline=deadline)
    heights = opts.heights
    if heights is None:  # on with fixed goals, up to HEIGHTS_MAX_VEHICLES (SwarmOptions)
        heights = scenario.assign_goals is None and problem.n_agents <= HEIGHTS_MAX_VEHICLES
        if scenario.assign_goals is None and not heights:
            extra["heights"] = f"both wavefronts: not planned (more than {HEIGHTS_MAX_VEHICLES} vehicles)"
    if heights and opts.prioritized and not straight:
        got = _heights_way(problem, lower_bound, opts, found, by_agent, extra, progress=progress, deadline=deadline)
        if got is not None:
            found, by_agent, retiming = got
            initial = max(tr.arrival_s for tr in found.tracks)
    repair = None
    if _repairs(opts, found):  # once, on the plan kept (SwarmOptions.makespan_repair)
        repair = _makespan_stage(problem, by_agent, opts, progress=progress, deadline=deadline)
    # single-vehicle searches given back by the memo (swarm.memo) and searched, over every stage
    extra.setdefault("counts", {}).update(searches_recalled=problem.memo.hits, searches_run=problem.memo.misses)
    info = SwarmInfo(
        stage=found.stage,
        coordination=found.coordination,
        vehicles=problem.n_agents,
        lower_bound_s=lower_bound,
        initial_makespan_s=initial,
        makespan_s=max(tr.arrival_s for tr in by_agent.values()),
        time_s=round(time.perf_counter() - t0, 3),
        retiming=retiming,
        makespan_repair=repair,
        **extra,
    )
    timed = {problem.names[a]: by_agent[a].timed_path() for a in range(problem.n_agents)}
    return timed, info


def _heights_way(
    problem: SwarmProblem,
    lower_bound_s: float,
    opts: SwarmOptions,
    found: _Stage,
    by_agent: dict[int, GridTrack],
    extra: dict,
    *,
    progress,
    deadline,
) -> tuple[_Stage, dict[int, GridTrack], RetimeInfo] | None:
    """``SwarmOptions.heights``: one more pass of prioritised planning, with both wavefronts per
    vehicle, in the order and hold of the pass that gave the plan without (``found``, already through
    its tail: ``by_agent``), on what is left of prioritised planning's count budget (a pass that
    cannot finish within it gives up early, charged the rest); re-timed as the plan without, that
    whole plan when it is shorter (then (stage, tracks, re-timing)), else None (the makespan repair
    runs after this choice, on the plan kept).
    No pass where prioritised planning did not give the plan (it gave up: its budget is spent; the
    lattice plan) or left no budget. What it gave is said in ``extra["heights"]``; its plannings are
    counted apart (``heights_planned``)."""
    without = max(tr.arrival_s for tr in by_agent.values())
    counts = extra.setdefault("counts", {})
    left = prioritised_budget(problem, opts) - counts.get("charged", 0)
    if found.pass_key is None or left <= 0:
        if found.stage == "lattice":
            why = "prioritised planning gave up: its budget spent"
        elif found.pass_key is None:
            why = "the plan with straight lines kept"
        else:
            why = "no planning budget left"
        extra["heights"] = f"both wavefronts: not planned ({why}); kept the plan without, {without:.2f} s"
        counts["heights_planned"] = 0
        return None
    mine: dict = {}
    alt = _prioritised_stage(
        problem,
        lower_bound_s,
        opts,
        mine,
        progress=progress,
        deadline=deadline,
        heights=True,
        only=found.pass_key,
        budget=left,
    )
    counts["heights_planned"] = mine["counts"]["planned"]
    extra["heights_time_s"] = mine["prioritised_time_s"]
    if alt is None:
        extra["heights"] = f"both wavefronts: gave up ({mine['prioritised']}); kept the plan without, {without:.2f} s"
        return None
    same = found.stage == "prioritised" and all(
        track_digest(a) == track_digest(b) for a, b in zip(alt.tracks, found.tracks)
    )
    if same:
        extra["heights"] = f"both wavefronts: the same tracks as without ({mine['prioritised']})"
        return None
    initial = max(tr.arrival_s for tr in alt.tracks)
    alt_by_agent, retiming = _retime_stage(problem, alt, initial, opts, progress=progress, deadline=deadline)
    makespan = max(tr.arrival_s for tr in alt_by_agent.values())
    keep = makespan < without
    extra["heights"] = (
        f"both wavefronts: {makespan:.2f} s ({mine['prioritised']}); without: {without:.2f} s ({found.stage}); "
        + ("kept both wavefronts" if keep else "kept the plan without")
    )
    if not keep:
        return None
    return alt, alt_by_agent, retiming


def _straight(problem: SwarmProblem) -> Callable[[int], list[np.ndarray]]:
    return lambda a: [np.array([problem.starts_m[a], problem.goals_m[a]])]


def _own_routes(problem: SwarmProblem, tracks: list[GridTrack]) -> Callable[[int], list[np.ndarray]]:
    """The straight line and the route each vehicle's track was timed along (re-timing)."""
    routes = {tr.agent: tr.route_m for tr in tracks}

    def chains(a: int) -> list[np.ndarray]:
        out = [np.array([problem.starts_m[a], problem.goals_m[a]])]
        r = routes.get(a)
        if r is not None and len(r) > 2:
            out.append(r)
        return out

    return chains


def _straight_stage(problem: SwarmProblem) -> _Stage:
    """Every vehicle on its straight line in one synchronised step (no pair conflicts)."""
    straight = straight_tracks(problem, list(range(problem.n_agents)))
    tracks = [straight[a] for a in range(problem.n_agents)]
    return _Stage(tracks, "straight", "one synchronised straight step", _straight(problem))


def longest_first(problem: SwarmProblem) -> list[int]:
    """Planning order: the longer straight line first (it sets the makespan), ties by index."""
    length = np.linalg.norm(problem.goals_m - problem.starts_m, axis=1)
    return sorted(range(problem.n_agents), key=lambda a: (-float(length[a]), a))


ORDERS: dict[str, Callable[[SwarmProblem], list[int]]] = {
    "dependencies first": dependency_order,
    "longest first": longest_first,
}


def prioritised_budget(problem: SwarmProblem, opts: SwarmOptions) -> int:
    """Single-vehicle plannings of prioritised planning over all its passes (``opts.plannings_per_vehicle``
    per vehicle; the pass with both wavefronts, ``SwarmOptions.heights``, spends what is left)."""
    return math.ceil(opts.plannings_per_vehicle * problem.n_agents)


def _makespan(stage: _Stage) -> float:
    return max(tr.arrival_s for tr in stage.tracks)


def _horizon_steps(lower_bound_s: float) -> int:
    horizon_s = max(PRIORITISED_HORIZON_FACTOR * lower_bound_s, lower_bound_s + PRIORITISED_HORIZON_MARGIN_S)
    return int(round(horizon_s / GRID_DT_S))


def _kept_straight_stage(
    problem: SwarmProblem, lower_bound_s: float, opts: SwarmOptions, extra: dict, *, progress, deadline
) -> _Stage | None:
    """Straight lines where they conflict with nobody, prioritised planning with repair for the
    rest (:func:`~proxplan.planner.swarm.straight.kept_straight_lines`); None when it gives up or
    keeps no line (then it is prioritised planning of everyone)."""
    if not opts.keep_straight:
        return None
    horizon = _horizon_steps(lower_bound_s)
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
    return _Stage(tracks, "prioritised", coordination, _own_routes(problem, tracks))


def _prioritised_stage(
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
) -> _Stage | None:
    """Prioritised continuous planning of each group of vehicles that interact, in each of
    ``opts.orders``, the shorter plan kept; each order with the first of ``opts.unplanned_hold_s``
    for which it finds a plan; all within a count of single-vehicle plannings
    (``opts.plannings_per_vehicle``); None when every one gives up. With one group, a pass whose
    plannings left cannot plan the vehicles it still has queued gives up at once and is charged
    the whole budget left (``PriorityOptions.give_up_early``): it would spend it and give up all the
    same, so the same passes run after it and the plan is the same (``counts["planned"]`` counts
    the plannings made; ``counts["charged"]`` those charged). ``only``: the one (order label, hold)
    to run; ``budget``: the plannings of the whole stage (default ``opts.plannings_per_vehicle`` per
    vehicle)."""
    import os

    horizon = _horizon_steps(lower_bound_s)
    t1 = time.perf_counter()
    groups = interaction_groups(problem)
    workers = opts.workers if opts.workers > 0 else (os.cpu_count() or 1)
    tried = []
    best: _Stage | None = None
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
                best = _Stage(
                    tracks,
                    "prioritised",
                    f"prioritised continuous planning{', both wavefronts' if heights else ''}, {label}, vehicles not planned yet assumed to leave after "
                    f"{hold_s:g} s ({len(groups)} group(s), {result.planned} vehicle plannings, {result.repairs} "
                    f"repairs, {result.against_order} against the order)",
                    _own_routes(problem, tracks),
                    pass_key=(label, hold_s),
                )
            break  # a longer hold only where this one found nothing
    extra["prioritised"] = "; ".join(tried)
    extra["prioritised_time_s"] = round(time.perf_counter() - t1, 3)
    counts["charged"] = charged
    extra["counts"] = counts
    return best


def _lattice_stage(problem: SwarmProblem, opts: SwarmOptions, extra: dict, *, progress, deadline) -> _Stage:
    """LaCAM on the lattice, flown in lock-step: the guaranteed answer (or PlanNotFound)."""
    lattice = build_lattice(problem, max_run=opts.max_run)
    sync = SyncTable(problem.keepouts, problem.type_index, lattice.pos_mm)
    t1 = time.perf_counter()
    result = Lacam(lattice, sync, seed=opts.seed).solve(
        max_nodes=opts.max_nodes, max_proposals=opts.max_proposals, deadline=deadline, progress=progress
    )
    configurations = result.configurations
    extra["lattice"] = LatticeInfo(
        spacing_m=lattice.spacing_m,
        levels_m=lattice.levels_m.tolist(),
        vertices=int(lattice.pos_m.shape[0]),
        steps=len(configurations) - 1,
        nodes=result.nodes,
        tests=result.tests,
        time_s=round(time.perf_counter() - t1, 3),
    )

    def routes(a: int, lattice: Lattice = lattice) -> list[np.ndarray]:
        return [np.array([problem.starts_m[a], problem.goals_m[a]]), route_chain(lattice, configurations, a)]

    coordination = (
        f"LaCAM: {len(configurations) - 1} steps, {result.nodes} configurations, {result.tests} exact pair tests"
    )
    return _Stage(lockstep_tracks(lattice, configurations), "lattice", coordination, routes)


def _retime_stage(
    problem: SwarmProblem, found: _Stage, initial_s: float, opts: SwarmOptions, *, progress, deadline
) -> tuple[dict[int, GridTrack], RetimeInfo]:
    """Gauss-Seidel re-timing of every vehicle along its chains (never worse, conflict-free)."""
    by_agent = {tr.agent: tr for tr in found.tracks}
    horizon = int(round((initial_s + HORIZON_MARGIN_S) / GRID_DT_S))
    occ = Occupancy(problem, found.tracks, horizon)
    t2 = time.perf_counter()
    counts = improve(
        occ,
        by_agent,
        found.routes,
        passes=opts.passes,
        through=opts.through_waypoints != "never",
        progress=progress,
        deadline=deadline,
    )
    return by_agent, RetimeInfo(**counts, time_s=round(time.perf_counter() - t2, 3))


def _repairs(opts: SwarmOptions, found: _Stage) -> bool:
    """Whether the makespan repair runs on the plan of ``found`` (``SwarmOptions.makespan_repair``;
    None: not on the lattice plan, on elsewhere)."""
    if opts.makespan_repair is not None:
        return opts.makespan_repair
    return found.stage != "lattice"


def _makespan_stage(
    problem: SwarmProblem, by_agent: dict[int, GridTrack], opts: SwarmOptions, *, progress, deadline
) -> MakespanRepairInfo:
    """The latest vehicles planned again with those in their way (:mod:`proxplan.planner.swarm.makespan`;
    ``by_agent`` changed in place; never longer, always conflict-free)."""
    before = max(tr.arrival_s for tr in by_agent.values())
    if progress:
        progress("makespan repair", 0.9)
    t0 = time.perf_counter()
    counts = shorten_makespan(
        problem,
        by_agent,
        int(round((before + HORIZON_MARGIN_S) / GRID_DT_S)),
        through=opts.through_waypoints == "always",
        max_plannings=makespan_budget(problem.n_agents),
        deadline=deadline,
    )
    return MakespanRepairInfo(
        makespan_before_s=before,
        makespan_after_s=max(tr.arrival_s for tr in by_agent.values()),
        time_s=round(time.perf_counter() - t0, 3),
        **counts,
    )
