"""The stages of one swarm plan, in order (:func:`plan_stages`; the overview: :mod:`proxplan.planner.swarm.plan`):
straight first, prioritised planning (kept straight lines beside it, the vehicles giving way where
goals were assigned), the stacked plan beside it or the lattice plan and the stacked plan where it
gave up, re-timing, the pass with both wavefronts, the makespan repair; and each level of the stacked
plan planned by the same stages with its own options (:func:`level_options`, :func:`level_planner`).
World frame, z up, m, s."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from proxplan.planner.errors import PlanNotFound
from proxplan.planner.swarm.complete_stages import (
    BesideLevels,
    gave_up,
    join_levels,
    lattice_stage,
    stacked_beside,
    stacked_while_shorter,
    stacked_without_lattice,
    stage_makespan,
    straight_stage,
)
from proxplan.planner.swarm.give_way import yielding_candidate
from proxplan.planner.swarm.heights import heights_on, heights_pass
from proxplan.planner.swarm.info import (
    GiveUpHandOn,
    LevelHandOn,
    RetimeInfo,
    SwarmStage,
)
from proxplan.planner.swarm.lanes import lanes_stage
from proxplan.planner.swarm.levels import stack_levels
from proxplan.planner.swarm.options import SwarmOptions
from proxplan.planner.swarm.planned import Planned
from proxplan.planner.swarm.prioritised_stage import (
    FAR_GOALS_FIRST,
    horizon_steps,
    kept_straight_stage,
    prioritised_stage,
)
from proxplan.planner.swarm.problem import SwarmProblem
from proxplan.planner.swarm.repair_stage import makespan_stage, repairs
from proxplan.planner.swarm.retime_stage import retime_stage
from proxplan.planner.swarm.stage import Stage
from proxplan.planner.swarm.straight import straight_step_conflicts
from proxplan.planner.swarm.tracks import GRID_DT_S, GridTrack
from proxplan.planner.swarm.verify_guard import Check
from proxplan.planner.ties import TIME_RESOLUTION_S, shorter, tie_key
from proxplan.planner.timing.profile import rest_to_rest

__all__ = ["level_options", "level_planner", "plan_stages", "stacked_stage"]


def plan_stages(
    problem: SwarmProblem,
    lower_bound: float,
    opts: SwarmOptions,
    assigned: bool,
    stacking: Callable[[], dict] | None,
    *,
    progress,
    deadline,
    check: Check | None = None,
    level: bool = False,
    enough_bound_s: float | None = None,
) -> Planned:
    """The stages of the module on ``problem`` (``lower_bound``: its straight-line bound, s;
    ``assigned``: the goals were assigned; ``stacking``: gives the keep-outs the levels of the stacked plan are
    stacked on, :func:`~proxplan.planner.swarm.levels.stacking_keepouts`, called only where that plan is
    tried; None: no stacked plan; ``check``: whether tracks pass the verifier, asked after the makespan
    repair changed the stacked plan, :class:`~proxplan.planner.swarm.verify_guard.VerifyGuard`; ``level``:
    one level of the stacked plan, where the vehicles passing together are not tried: the join re-times
    their arcs as corner chains, pillar-64 by type 1.83x -> 2.60x, round 23S; ``enough_bound_s``: the bound
    ``opts.enough_factor`` multiplies, :func:`~proxplan.planner.swarm.enough.enough_bound_s`, s; None:
    ``lower_bound``)."""
    conflicts = straight_step_conflicts(problem)
    extra: dict = {}
    pre_retimed: tuple[dict[int, GridTrack], RetimeInfo] | None = None  # ``found`` re-timed, where already
    found = straight_stage(problem) if not conflicts else None
    straight = found is not None
    early = None  # interchangeable goals: a plan giving way within enough_factor of the bound (round 25S)
    if found is None and assigned and opts.prioritized and opts.enough_factor is not None and not level:
        early = yielding_candidate(
            problem,
            horizon_steps(lower_bound),
            extra,
            shorter_than_s=opts.enough_factor * (lower_bound if enough_bound_s is None else enough_bound_s),
            pairs=conflicts,
            together=opts.pass_together,
        )
        found = early
        if early is None:  # said again below, after the plan in hand
            extra["yielding"] = (
                f"within {opts.enough_factor:g}x the bound, before prioritised planning: {extra['yielding']}"
            )
    if found is None and opts.prioritized:
        kept = kept_straight_stage(problem, lower_bound, opts, extra, progress=progress, deadline=deadline)
        found = prioritised_stage(problem, lower_bound, opts, extra, progress=progress, deadline=deadline)
        if kept is not None and (found is None or shorter(stage_makespan(kept), stage_makespan(found))):
            found = kept
        if found is None and level:  # two-way lanes where prioritised planning gave up on a level (round 27A)
            found = lanes_stage(problem, lower_bound, extra)
    if assigned and conflicts and opts.prioritized and early is None:  # one vehicle of a pair yields (round 20S)
        in_hand = None if found is None else stage_makespan(found)
        together = opts.pass_together and not level
        yielded = yielding_candidate(
            problem, horizon_steps(lower_bound), extra, shorter_than_s=in_hand, pairs=conflicts, together=together
        )
        if yielded is not None and found is None:
            found = yielded
        elif yielded is not None and found is not None:  # the shorter once re-timed (round 21S: random-1 was
            retimed = [  # shorter before re-timing, longer after); ties: the plan in hand
                (
                    stage,
                    retime_stage(problem, stage, stage_makespan(stage), opts, progress=progress, deadline=deadline),
                )
                for stage in (found, yielded)
            ]
            found, pre_retimed = min(
                retimed, key=lambda r: tie_key(max(tr.arrival_s for tr in r[1][0].values()), TIME_RESOLUTION_S)
            )
    give_up: GiveUpHandOn | None = None
    if found is not None and not straight and not assigned and opts.levels and stacking is not None:
        # the stacked plan beside the prioritised plan, the shorter kept (round 24B)
        stack = stack_levels(problem, stacking())
        beside: list[LevelHandOn] = []
        planner = level_planner(opts, assigned, beside, progress=progress, deadline=deadline)
        bounded = BesideLevels(problem, stack, stage_makespan(found), planner)  # only while it can be shorter (25A)
        stacked, could = stacked_while_shorter(problem, extra, bounded)
        if could:  # else no level depends on the options: nothing handed on (swarm_again)
            give_up = GiveUpHandOn(
                found, stack, tuple(beside) if stacked is not None else None, beside_prioritised=True
            )
            found = stacked_beside(found, stacked, extra)
    if found is None:
        if progress:
            progress(f"coordination: lattice ({len(conflicts)} straight-line conflicts)", 0.05)
        lacam_not_found: PlanNotFound | None = None
        try:
            lattice: Stage | None = lattice_stage(problem, opts, extra, progress=progress, deadline=deadline)
        except PlanNotFound as err:  # LaCAM's budget: the stacked plan may still give one (round 19C)
            if not (opts.levels and stacking is not None) or (deadline is not None and time.perf_counter() > deadline):
                raise
            lattice, lacam_not_found = None, err
        stack = stack_levels(problem, stacking()) if opts.levels and stacking is not None else None
        levels: list[LevelHandOn] = []
        stacked = None
        bound_first = False  # no stacked plan could be shorter, whatever its levels' plans (nothing handed on)
        if opts.levels and stacking is not None:
            planner = level_planner(opts, assigned, levels, progress=progress, deadline=deadline)
            rival_s = math.inf if lattice is None else stage_makespan(lattice)
            bounded = BesideLevels(problem, stack, rival_s, planner, rival="the lattice plan")  # round 25A
            stacked, could = stacked_while_shorter(problem, extra, bounded)
            bound_first = not could
        if lattice is None:
            found = stacked_without_lattice(stacked, lacam_not_found, opts, extra)
        else:
            handed = None if bound_first else stack  # swarm_again: the lattice plan again, as here
            give_up = GiveUpHandOn(lattice, handed, tuple(levels) if stacked is not None else None)
            found = gave_up(lattice, stacked, opts, extra)
    searched = found
    initial = max(tr.arrival_s for tr in found.tracks)
    if pre_retimed is not None:
        by_agent, retiming = pre_retimed
    else:
        by_agent, retiming = retime_stage(problem, found, initial, opts, progress=progress, deadline=deadline)
    heights = heights_on(opts, assigned, problem.n_agents, extra)
    heights_stage: list[Stage] = []  # the pass's tracks, where it gave other tracks (then re-timed here)
    if heights and opts.prioritized and not straight and found.stage != "stacked":

        def retime(stage: Stage) -> tuple[dict[int, GridTrack], RetimeInfo]:
            heights_stage.append(stage)
            return retime_stage(problem, stage, stage_makespan(stage), opts, progress=progress, deadline=deadline)

        got = heights_pass(
            problem, lower_bound, opts, found, by_agent, extra, retime, progress=progress, deadline=deadline
        )
        if got is not None:
            found, by_agent, retiming = got
            initial = max(tr.arrival_s for tr in found.tracks)
    repair = None
    if repairs(opts, found):  # once, on the plan kept (SwarmOptions.makespan_repair)
        guard = check if found.stage == "stacked" else None
        repair = makespan_stage(problem, by_agent, opts, progress=progress, deadline=deadline, check=guard)
    alt = heights_stage[0] if heights_stage else None
    return Planned(found, by_agent, initial, retiming, repair, extra, searched, alt, give_up)


def level_options(opts: SwarmOptions) -> SwarmOptions:
    """The options each level of the stacked plan is planned with: by the stages of :func:`plan_stages` with
    prioritised planning in the first order and the goal block filled from its far side (swarm.fill_order;
    the shorter kept, ties the first: a level of pillar-64 9.88 s against 11.35 s, corridor-64 4.27x ->
    4.13x, grid-64 the same plan; round 24B), no pass with both wavefronts and no makespan repair:
    with all of them corridor-64 fixed took 42.6 s of CPU (the issue's target is 30 s) for the same plan
    (4.84x) and grid-64 gave 2.11x instead of 2.21x (set watching these two named layouts;
    docs/planner.md, stop 52 round 14A)."""
    orders = tuple(dict.fromkeys((opts.orders[0], FAR_GOALS_FIRST)))
    return replace(opts, levels=False, heights=False, makespan_repair=False, orders=orders)


def stacked_stage(
    problem: SwarmProblem, opts: SwarmOptions, assigned: bool, stacking: dict, extra: dict, *, progress, deadline
) -> Stage | None:
    """The stacked plan alone (:func:`~proxplan.planner.swarm.complete_stages.join_levels` on :func:`~proxplan.planner.swarm.levels.stack_levels`
    of ``stacking``, each level planned by :func:`level_planner`)."""
    planner = level_planner(opts, assigned, [], progress=progress, deadline=deadline)
    return join_levels(problem, stack_levels(problem, stacking), extra, planner)


def level_planner(
    opts: SwarmOptions, assigned: bool, record: list[LevelHandOn], *, progress, deadline
) -> Callable[[SwarmProblem], tuple[list[GridTrack], SwarmStage, int]]:
    """Plans one level of the stacked plan by :func:`plan_stages` with :func:`level_options` (its tracks,
    the stage that gave them, the vehicle plannings made), appending what it planned to ``record``."""

    def plan_level(sub: SwarmProblem) -> tuple[list[GridTrack], SwarmStage, int]:
        bound = max(
            rest_to_rest(float(np.linalg.norm(sub.goals_m[a] - sub.starts_m[a])), sub.limits[a], GRID_DT_S).duration_s
            for a in range(sub.n_agents)
        )
        level = plan_stages(
            sub, bound, level_options(opts), assigned, None, progress=progress, deadline=deadline, level=True
        )
        made = level.extra.get("counts", {})
        planned = made.get("planned", 0) + made.get("heights_planned", 0)
        record.append(LevelHandOn(sub, level.searched, planned))
        return [level.tracks[a] for a in range(sub.n_agents)], level.stage.stage, planned

    return plan_level
