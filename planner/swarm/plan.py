"""Swarm planning (``--method swarm``; ``optimized`` for swarms of ``SWARM_MIN_VEHICLES`` or
more): coordinate jointly on a lattice, fly in continuous time. One function per stage:

1. *Straight first* (:func:`~proxplan.planner.swarm.complete_stages.straight_stage`, :mod:`proxplan.planner.swarm.straight`): if every
   vehicle can fly its straight line at once, synchronised (one step, checked exactly pair by pair),
   that is the plan (the CAPT case of interchangeable goals).
2. *Continuous time, prioritised* (:mod:`proxplan.planner.swarm.prioritised_stage`, planning by
   :mod:`proxplan.planner.swarm.priority`), two ways, the shorter plan kept: the straight lines in no
   conflict kept and only the other vehicles planned around them (``kept_straight_stage``), and every
   vehicle in each of ``SwarmOptions.orders`` (``prioritised_stage``; groups that never interact apart,
   :mod:`proxplan.planner.swarm.components`). One vehicle after another along the best of its
   straight line and a wavefront route through the others' space-time, timed exactly; vehicles
   not planned yet are predictions; a vehicle that cannot be planned is repaired (only the vehicles
   in conflict with it planned again, after it), within a count of repairs per pass; one still
   failing then flies in collision and the collisions are repaired at the end of the pass
   (:mod:`proxplan.planner.swarm.lns`). With ``SwarmOptions.heights`` (on with fixed goals up to
   ``HEIGHTS_MAX_VEHICLES``; :mod:`proxplan.planner.swarm.heights`), once the prioritised plan is
   re-timed (4), one more pass runs, in its order and hold, with both wavefronts per vehicle (the
   earlier arrival kept), on what is left of the count budget; it is re-timed too and replaces that
   plan only when it is shorter: a vehicle's earlier arrival can lengthen the whole plan. None where
   prioritised planning gave up. Where goals were assigned, the vehicles giving way
   (:mod:`proxplan.planner.swarm.give_way`: passing together, yielding) are tried first, asked for a plan
   within ``SwarmOptions.enough_factor`` of the lower bound; where they give one, prioritised planning is
   not run (round 25S); else they are asked again after it, for a plan shorter than its plan.
3. *Joint coordination*, when prioritised planning gives up (:func:`~proxplan.planner.swarm.complete_stages.lattice_stage`): LaCAM with
   PIBT on the lattice of the levels in use, long straight moves, synchronous conflicts checked
   exactly (:mod:`proxplan.planner.swarm.lacam`, a count of configurations bounds it), flown in
   lock-step (:mod:`proxplan.planner.swarm.lockstep`): conflict-free by construction, the
   guaranteed answer. Beside it (``SwarmOptions.levels``) the *stacked plan*
   (:func:`_stacked_stage`, :mod:`proxplan.planner.swarm.stacked`): each group of types on a level of
   its own where the box is tall enough, each level planned apart by these stages (prioritised
   planning in the first order and in the goal block filled from its far side,
   :mod:`proxplan.planner.swarm.fill_order`; the shorter level kept); the shorter kept. With fixed
   goals the stacked plan is also made beside a prioritised plan (2), and kept where it is shorter
   before re-timing (:func:`~proxplan.planner.swarm.complete_stages.stacked_beside`; round 24B). Beside
   either plan its levels are planned only while it can still be shorter
   (:class:`~proxplan.planner.swarm.complete_stages.BesideLevels`; round 25A).
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
of any vehicle) and the makespans after each stage. The knobs of every stage are
:class:`~proxplan.planner.swarm.options.SwarmOptions`; a stage hands its tracks on as a
:class:`~proxplan.planner.swarm.stage.Stage`.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from proxplan.planfile import Scenario
from proxplan.planner.errors import PlanNotFound
from proxplan.planner.sampling.ordering import lower_bound_makespan_s
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
from proxplan.planner.swarm.frozen import apply_unfreezes, moved_points, unfrozen_problem
from proxplan.planner.swarm.give_way import yielding_candidate
from proxplan.planner.swarm.heights import heights_on, heights_pass
from proxplan.planner.swarm.info import (
    GiveUpHandOn,
    LevelHandOn,
    MakespanRepairInfo,
    RetimeInfo,
    SwarmHandOn,
    SwarmInfo,
    SwarmStage,
)
from proxplan.planner.swarm.lanes import lanes_stage
from proxplan.planner.swarm.levels import stack_levels, stacking_keepouts
from proxplan.planner.swarm.makespan import budget as makespan_budget
from proxplan.planner.swarm.makespan import shorten_makespan
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.options import SwarmOptions
from proxplan.planner.swarm.prioritised_stage import (
    FAR_GOALS_FIRST,
    horizon_steps,
    kept_straight_stage,
    prioritised_stage,
)
from proxplan.planner.swarm.problem import SwarmProblem, swarm_applicable, swarm_problem
from proxplan.planner.swarm.retime import improve
from proxplan.planner.swarm.stage import Stage
from proxplan.planner.swarm.straight import straight_step_conflicts
from proxplan.planner.swarm.tracks import GRID_DT_S, GridTrack
from proxplan.planner.swarm.verify_guard import Check, VerifyGuard
from proxplan.planner.timing.paths import TimedPath
from proxplan.planner.timing.profile import rest_to_rest

SWARM_MIN_VEHICLES = 16  # formation changes with at least this many vehicles use the swarm layer by default
HORIZON_MARGIN_S = 5.0  # the re-timing horizon extends this far past the initial makespan, s

__all__ = ["SWARM_MIN_VEHICLES", "SwarmHandOn", "SwarmOptions", "swarm_again", "swarm_applicable", "swarm_timed"]


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
    original = swarm_problem(scenario, deflection_m=opts.deflection_m, tracking_bound=opts.tracking_bound)
    problem, unfreezes, frozen = unfrozen_problem(original)  # frozen pairs at the starts / goals (swarm.frozen)
    lower_bound = lower_bound_makespan_s(scenario)
    try:
        planned = _plan(
            problem,
            lower_bound,
            opts,
            scenario.assign_goals is not None,
            _stacking(scenario, problem) if opts.levels else None,
            progress=progress,
            deadline=deadline,
            check=VerifyGuard(scenario, problem, original, unfreezes),
        )
    except PlanNotFound as err:
        if not frozen:
            raise
        raise PlanNotFound(f"{err.message} ({frozen})", vehicles=err.vehicles, details=err.details) from err
    timed, info = _handed_on(problem, lower_bound, opts, scenario.assign_goals is not None, planned, t0, (0, 0))
    if not unfreezes:
        return timed, info
    timed, added = apply_unfreezes(timed, original, unfreezes, GRID_DT_S)
    return timed, replace(
        info,
        coordination=f"{frozen}; {info.coordination}",
        initial_makespan_s=info.initial_makespan_s + added,
        makespan_s=max(p.duration_s for p in timed.values()),
    )


def swarm_again(
    scenario: Scenario,
    hand_on: SwarmHandOn,
    options: SwarmOptions,
    *,
    progress: Callable[[str, float], None] | None = None,
    deadline: float | None = None,
) -> tuple[dict[str, TimedPath], SwarmInfo]:
    """What :func:`swarm_timed` gives for ``scenario`` with ``options``, reusing what the plan of
    ``hand_on`` computed: where ``options`` differ from that plan's only in ``through_waypoints``
    between "never" and "retime" (the searches are the same: only "always" reaches them), its own
    tracks before re-timing re-timed again (and the pass with both wavefronts' tracks, where that pass
    gave other tracks; where prioritised planning gave up, the stacked plan's levels re-timed again and
    joined, beside the lattice plan; the makespan repair after, on the plan kept); elsewhere, where the problem is
    the same (``deflection_m``, ``tracking_bound``), the stages planned on that problem (its keep-outs,
    its memo of single-vehicle searches); else :func:`swarm_timed`. The same tracks as
    :func:`swarm_timed` with ``options`` (the memo gives back what a search would find)."""
    if moved_points(scenario, hand_on.problem):  # its unfreeze step (swarm.frozen) is not handed on: afresh
        return swarm_timed(scenario, options, progress=progress, deadline=deadline)
    before = hand_on.options
    searches = ("never", "retime")
    if before.through_waypoints in searches and options.through_waypoints in searches:
        give_up = hand_on.give_up
        joined = give_up is None or give_up.stack is None or give_up.levels is not None
        if replace(options, through_waypoints=before.through_waypoints) == before and joined:
            check = VerifyGuard(scenario, hand_on.problem, hand_on.problem, ())
            return _retimed_again(hand_on, options, progress=progress, deadline=deadline, check=check)
    if (options.deflection_m, options.tracking_bound) != (before.deflection_m, before.tracking_bound):
        return swarm_timed(scenario, options, progress=progress, deadline=deadline)
    t0 = time.perf_counter()
    problem = hand_on.problem
    memo = (problem.memo.hits, problem.memo.misses)
    planned = _plan(
        problem,
        hand_on.lower_bound_s,
        options,
        hand_on.assigned,
        _stacking(scenario, problem) if options.levels else None,
        progress=progress,
        deadline=deadline,
        check=VerifyGuard(scenario, problem, problem, ()),
    )
    return _handed_on(problem, hand_on.lower_bound_s, options, hand_on.assigned, planned, t0, memo)


def _stacking(scenario: Scenario, problem: SwarmProblem) -> Callable[[], dict]:
    """The keep-outs the stacked plan's levels are stacked on, built only when called (where that plan
    is tried: prioritised planning gave up)."""

    def stacking() -> dict:
        from proxplan.costmaps import effects_key  # as swarm_problem does

        fx = effects_key(getattr(scenario, "effects", ()))
        return stacking_keepouts(problem, scenario.limits, scenario.field_form, fx)

    return stacking


def _handed_on(
    problem: SwarmProblem,
    lower_bound: float,
    opts: SwarmOptions,
    assigned: bool,
    planned: _Planned,
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


def _retimed_again(
    hand_on: SwarmHandOn, opts: SwarmOptions, *, progress, deadline, check: Check | None = None
) -> tuple[dict[str, TimedPath], SwarmInfo]:
    """:func:`swarm_again` where only the re-timing differs: the tail of :func:`_plan` (re-timing,
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
                by, _ = _retime_stage(
                    level,
                    searched,
                    stage_makespan(searched),
                    _level_options(opts),
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
    by_agent, retiming = _retime_stage(
        problem, found, stage_makespan(found), opts, progress=progress, deadline=deadline
    )
    if hand_on.heights is not None:  # as heights_pass chose: that plan when shorter once re-timed
        alt = hand_on.heights
        alt_by_agent, alt_retiming = _retime_stage(
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
    if _repairs(opts, found):
        guard = check if found.stage == "stacked" else None
        repair = _makespan_stage(problem, by_agent, opts, progress=progress, deadline=deadline, check=guard)
    planned = _Planned(
        found, by_agent, stage_makespan(found), retiming, repair, extra, searched, hand_on.heights, give_up
    )
    return _handed_on(problem, hand_on.lower_bound_s, opts, hand_on.assigned, planned, t0, memo)


@dataclass
class _Planned:
    """What the stages of :func:`_plan` give: the stage whose tracks were kept, the final tracks by agent,
    the makespan before re-timing (s), what re-timing and the makespan repair did, the other stages'
    records (``SwarmInfo``'s extra fields), and what :class:`SwarmHandOn` hands on: the searched stage's
    tracks before re-timing, the pass with both wavefronts' (where it gave other tracks) and the
    give-up plans (where prioritised planning gave up)."""

    stage: Stage
    tracks: dict[int, GridTrack]
    initial_makespan_s: float
    retiming: RetimeInfo
    repair: MakespanRepairInfo | None
    extra: dict
    searched: Stage
    heights: Stage | None
    give_up: GiveUpHandOn | None = None


def _plan(
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
) -> _Planned:
    """The stages of the module on ``problem`` (``lower_bound``: its straight-line bound, s;
    ``assigned``: the goals were assigned; ``stacking``: gives the keep-outs the levels of the stacked plan are
    stacked on, :func:`~proxplan.planner.swarm.levels.stacking_keepouts`, called only where that plan is
    tried; None: no stacked plan; ``check``: whether tracks pass the verifier, asked after the makespan
    repair changed the stacked plan, :class:`~proxplan.planner.swarm.verify_guard.VerifyGuard`; ``level``:
    one level of the stacked plan, where the vehicles passing together are not tried: the join re-times
    their arcs as corner chains, pillar-64 by type 1.83x -> 2.60x, round 23S)."""
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
            shorter_than_s=opts.enough_factor * lower_bound,
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
        if kept is not None and (found is None or stage_makespan(kept) < stage_makespan(found)):
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
                    _retime_stage(problem, stage, stage_makespan(stage), opts, progress=progress, deadline=deadline),
                )
                for stage in (found, yielded)
            ]
            found, pre_retimed = min(retimed, key=lambda r: max(tr.arrival_s for tr in r[1][0].values()))
    give_up: GiveUpHandOn | None = None
    if found is not None and not straight and not assigned and opts.levels and stacking is not None:
        # the stacked plan beside the prioritised plan, the shorter kept (round 24B)
        stack = stack_levels(problem, stacking())
        beside: list[LevelHandOn] = []
        planner = _level_planner(opts, assigned, beside, progress=progress, deadline=deadline)
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
            planner = _level_planner(opts, assigned, levels, progress=progress, deadline=deadline)
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
        by_agent, retiming = _retime_stage(problem, found, initial, opts, progress=progress, deadline=deadline)
    heights = heights_on(opts, assigned, problem.n_agents, extra)
    heights_stage: list[Stage] = []  # the pass's tracks, where it gave other tracks (then re-timed here)
    if heights and opts.prioritized and not straight and found.stage != "stacked":

        def retime(stage: Stage) -> tuple[dict[int, GridTrack], RetimeInfo]:
            heights_stage.append(stage)
            return _retime_stage(problem, stage, stage_makespan(stage), opts, progress=progress, deadline=deadline)

        got = heights_pass(
            problem, lower_bound, opts, found, by_agent, extra, retime, progress=progress, deadline=deadline
        )
        if got is not None:
            found, by_agent, retiming = got
            initial = max(tr.arrival_s for tr in found.tracks)
    repair = None
    if _repairs(opts, found):  # once, on the plan kept (SwarmOptions.makespan_repair)
        guard = check if found.stage == "stacked" else None
        repair = _makespan_stage(problem, by_agent, opts, progress=progress, deadline=deadline, check=guard)
    alt = heights_stage[0] if heights_stage else None
    return _Planned(found, by_agent, initial, retiming, repair, extra, searched, alt, give_up)


def _level_options(opts: SwarmOptions) -> SwarmOptions:
    """The options each level of the stacked plan is planned with: by the stages of _plan with
    prioritised planning in the first order and the goal block filled from its far side (swarm.fill_order;
    the shorter kept, ties the first: a level of pillar-64 9.88 s against 11.35 s, corridor-64 4.27x ->
    4.13x, grid-64 the same plan; round 24B), no pass with both wavefronts and no makespan repair:
    with all of them corridor-64 fixed took 42.6 s of CPU (the issue's target is 30 s) for the same plan
    (4.84x) and grid-64 gave 2.11x instead of 2.21x (set watching these two named layouts;
    docs/planner.md, stop 52 round 14A)."""
    orders = tuple(dict.fromkeys((opts.orders[0], FAR_GOALS_FIRST)))
    return replace(opts, levels=False, heights=False, makespan_repair=False, orders=orders)


def _stacked_stage(
    problem: SwarmProblem, opts: SwarmOptions, assigned: bool, stacking: dict, extra: dict, *, progress, deadline
) -> Stage | None:
    """The stacked plan alone (:func:`~proxplan.planner.swarm.complete_stages.join_levels` on :func:`~proxplan.planner.swarm.levels.stack_levels`
    of ``stacking``, each level planned by :func:`_level_planner`)."""
    planner = _level_planner(opts, assigned, [], progress=progress, deadline=deadline)
    return join_levels(problem, stack_levels(problem, stacking), extra, planner)


def _level_planner(
    opts: SwarmOptions, assigned: bool, record: list[LevelHandOn], *, progress, deadline
) -> Callable[[SwarmProblem], tuple[list[GridTrack], SwarmStage, int]]:
    """Plans one level of the stacked plan by :func:`_plan` with :func:`_level_options` (its tracks,
    the stage that gave them, the vehicle plannings made), appending what it planned to ``record``."""

    def plan_level(sub: SwarmProblem) -> tuple[list[GridTrack], SwarmStage, int]:
        bound = max(
            rest_to_rest(float(np.linalg.norm(sub.goals_m[a] - sub.starts_m[a])), sub.limits[a], GRID_DT_S).duration_s
            for a in range(sub.n_agents)
        )
        level = _plan(
            sub, bound, _level_options(opts), assigned, None, progress=progress, deadline=deadline, level=True
        )
        made = level.extra.get("counts", {})
        planned = made.get("planned", 0) + made.get("heights_planned", 0)
        record.append(LevelHandOn(sub, level.searched, planned))
        return [level.tracks[a] for a in range(sub.n_agents)], level.stage.stage, planned

    return plan_level


def _retime_stage(
    problem: SwarmProblem, found: Stage, initial_s: float, opts: SwarmOptions, *, progress, deadline
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


def _repairs(opts: SwarmOptions, found: Stage) -> bool:
    """Whether the makespan repair runs on the plan of ``found`` (``SwarmOptions.makespan_repair``;
    None: not on the lattice plan (lock-step tracks: nothing replaced on grid-64 and corridor-64 fixed,
    round 14A), on elsewhere. On the stacked plan it shortens grid-64 6.93 -> 5.58 s and grid-128 13.00
    -> 11.50 s; it was off there after stop 58 (grid-256 past 500 s of CPU): there its repaired plan
    failed verify (a vehicle flown between the levels adds its jet to the level above's on a vehicle
    below) and the pipeline planned again; now its result on the stacked plan is verified and given up
    where it fails, and its stall budget is counted in work (``makespan.STALL_WORK_STEPS``; round 21A)."""
    if opts.makespan_repair is not None:
        return opts.makespan_repair
    return found.stage != "lattice"


def _makespan_stage(
    problem: SwarmProblem,
    by_agent: dict[int, GridTrack],
    opts: SwarmOptions,
    *,
    progress,
    deadline,
    check: Check | None = None,
) -> MakespanRepairInfo:
    """The latest vehicles planned again with those in their way (:mod:`proxplan.planner.swarm.makespan`;
    ``by_agent`` changed in place; never longer, always conflict-free). ``check`` (the stacked plan:
    :class:`~proxplan.planner.swarm.verify_guard.VerifyGuard`): the repair plans against the pair
    keep-outs, and a vehicle it flies between the stacked plan's levels can add its jet to the level
    above's on a vehicle below (the levels are stacked so that two sources fit, levels.STACK_AUTHORITY_SHARE;
    grid-256: 0.119 of the 0.1 authority fraction, stop 59 round 21A), so such a track is taken only
    where the verifier's sums pass around it (``VerifyGuard.fits``); the whole result is asked once
    more after the repair replaced tracks, and where that fails the tracks before the repair come back
    (``MakespanRepairInfo.verify_failed``)."""
    before = max(tr.arrival_s for tr in by_agent.values())
    kept = dict(by_agent)
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
        fits=check.fits if isinstance(check, VerifyGuard) else None,
    )
    failed = check is not None and counts["replaced"] > 0 and not check(by_agent)
    if failed:
        by_agent.update(kept)
    return MakespanRepairInfo(
        makespan_before_s=before,
        makespan_after_s=max(tr.arrival_s for tr in by_agent.values()),
        time_s=round(time.perf_counter() - t0, 3),
        verify_failed=failed,
        refused=check.refused if isinstance(check, VerifyGuard) else 0,
        **counts,
    )
