"""What one swarm plan hands on and how it is planned again from it (:func:`handed_on`,
:func:`retimed_again`; :func:`proxplan.planner.swarm.plan.swarm_again`), and the keep-outs its stacked
plan's levels are stacked on, built when first needed (:func:`level_stacking`). World frame, z up, m, s."""

from __future__ import annotations

import time
from collections.abc import Callable

from proxplan.planfile import Scenario
from proxplan.planner.swarm.complete_stages import (
    gave_up,
    join_levels,
    stacked_beside,
    stage_makespan,
)
from proxplan.planner.swarm.info import (
    SwarmHandOn,
    SwarmInfo,
    SwarmStage,
)
from proxplan.planner.swarm.levels import stacking_keepouts
from proxplan.planner.swarm.options import SwarmOptions
from proxplan.planner.swarm.planned import Planned
from proxplan.planner.swarm.problem import SwarmProblem
from proxplan.planner.swarm.repair_stage import makespan_stage, repairs
from proxplan.planner.swarm.retime_stage import retime_stage
from proxplan.planner.swarm.stages import level_options
from proxplan.planner.swarm.tracks import GridTrack
from proxplan.planner.swarm.verify_guard import Check
from proxplan.planner.timing.paths import TimedPath

__all__ = ["handed_on", "level_stacking", "retimed_again"]


def level_stacking(scenario: Scenario, problem: SwarmProblem) -> Callable[[], dict]:
    """The keep-outs the stacked plan's levels are stacked on, built only when called (where that plan
    is tried: prioritised planning gave up)."""

    def stacking() -> dict:
        from proxplan.costmaps import effects_key  # as swarm_problem does

        fx = effects_key(getattr(scenario, "effects", ()))
        return stacking_keepouts(problem, scenario.limits, scenario.field_form, fx)

    return stacking


def handed_on(
    problem: SwarmProblem,
    lower_bound: float,
    opts: SwarmOptions,
    assigned: bool,
    planned: Planned,
    t0: float,
    memo_before: tuple[int, int],
) -> tuple[dict[str, TimedPath], SwarmInfo]:
    """The timed paths and the :class:`SwarmInfo` of ``planned`` (with its :class:`SwarmHandOn`);
    ``t0``: time.perf_counter() when planning began; ``memo_before``: the memo's (hits, misses) then."""
    found, by_agent, extra = planned.stage, planned.tracks, planned.extra
    hand_on = SwarmHandOn(
        problem=problem,
        options=opts,
        lower_bound_s=lower_bound,
        assigned=assigned,
        searched=planned.searched,
        heights=planned.heights,
        give_up=planned.give_up,
        tracks=dict(by_agent),
        extra={k: (dict(v) if isinstance(v, dict) else v) for k, v in extra.items()},
    )
    # single-vehicle searches given back by the memo (swarm.memo) and searched, over every stage
    extra.setdefault("counts", {}).update(
        searches_recalled=problem.memo.hits - memo_before[0], searches_run=problem.memo.misses - memo_before[1]
    )
    info = SwarmInfo(
        stage=found.stage,
        coordination=found.coordination,
        vehicles=problem.n_agents,
        lower_bound_s=lower_bound,
        initial_makespan_s=planned.initial_makespan_s,
        makespan_s=max(tr.arrival_s for tr in by_agent.values()),
        time_s=round(time.perf_counter() - t0, 3),
        retiming=planned.retiming,
        makespan_repair=planned.repair,
        hand_on=hand_on,
        **extra,
    )
    timed = {problem.names[a]: by_agent[a].timed_path() for a in range(problem.n_agents)}
    return timed, info


def retimed_again(
    hand_on: SwarmHandOn, opts: SwarmOptions, *, progress, deadline, check: Check | None = None
) -> tuple[dict[str, TimedPath], SwarmInfo]:
    """:func:`swarm_again` where only the re-timing differs: the tail of :func:`plan_stages` (re-timing,
    the choice with the pass with both wavefronts, the makespan repair) on the handed-on tracks."""
    t0 = time.perf_counter()
    problem = hand_on.problem
    memo = (problem.memo.hits, problem.memo.misses)
    extra = {k: (dict(v) if isinstance(v, dict) else v) for k, v in hand_on.extra.items()}
    found = hand_on.searched
    give_up = hand_on.give_up
    if give_up is not None:  # the stacked plan's levels were re-timed inside it: join them again
        stacked = None
        if give_up.levels is not None:
            records = iter(give_up.levels)

            def plan_level(sub: SwarmProblem) -> tuple[list[GridTrack], SwarmStage, int]:
                rec = next(records)
                assert rec.problem.names == sub.names, "the levels are planned in the order of the first run"
                level, searched = rec.problem, rec.searched
                by, _ = retime_stage(
                    level,
                    searched,
                    stage_makespan(searched),
                    level_options(opts),
                    progress=progress,
                    deadline=deadline,
                )
                return [by[a] for a in range(level.n_agents)], searched.stage, rec.planned

            stacked = join_levels(problem, give_up.stack, extra, plan_level)
        if give_up.beside_prioritised:
            found = stacked_beside(give_up.rival, stacked, extra)
        else:
            found = gave_up(give_up.rival, stacked, opts, extra)
    searched = found
    by_agent, retiming = retime_stage(problem, found, stage_makespan(found), opts, progress=progress, deadline=deadline)
    if hand_on.heights is not None:  # as heights_pass chose: that plan when shorter once re-timed
        alt = hand_on.heights
        alt_by_agent, alt_retiming = retime_stage(
            problem, alt, stage_makespan(alt), opts, progress=progress, deadline=deadline
        )
        without = max(tr.arrival_s for tr in by_agent.values())
        makespan = max(tr.arrival_s for tr in alt_by_agent.values())
        keep = makespan < without
        extra["heights"] = (
            f"both wavefronts (the pass planned before, re-timed again): {makespan:.2f} s; without: "
            f"{without:.2f} s ({found.stage}); " + ("kept both wavefronts" if keep else "kept the plan without")
        )
        if keep:
            found, by_agent, retiming = alt, alt_by_agent, alt_retiming
    repair = None
    if repairs(opts, found):
        guard = check if found.stage == "stacked" else None
        repair = makespan_stage(problem, by_agent, opts, progress=progress, deadline=deadline, check=guard)
    planned = Planned(
        found, by_agent, stage_makespan(found), retiming, repair, extra, searched, hand_on.heights, give_up
    )
    return handed_on(problem, hand_on.lower_bound_s, opts, hand_on.assigned, planned, t0, memo)
