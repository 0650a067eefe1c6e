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
   (:func:`~proxplan.planner.swarm.stages.stacked_stage`, :mod:`proxplan.planner.swarm.stacked`): each group of types on a level of
   its own where the box is tall enough, each level planned apart by these stages (prioritised
   planning in the first order and in the goal block filled from its far side,
   :mod:`proxplan.planner.swarm.fill_order`; the shorter level kept); the shorter kept. With fixed
   goals the stacked plan is also made beside a prioritised plan (2), and kept where it is shorter
   before re-timing (:func:`~proxplan.planner.swarm.complete_stages.stacked_beside`; round 24B). Beside
   either plan its levels are planned only while it can still be shorter
   (:class:`~proxplan.planner.swarm.complete_stages.BesideLevels`; round 25A).
4. *Re-timing* (:func:`~proxplan.planner.swarm.retime_stage.retime_stage`): Gauss-Seidel passes (:mod:`proxplan.planner.swarm.retime`),
   every vehicle against the others' tracks in a space-time neighbourhood; never worse, always
   conflict-free.
5. *Makespan repair* (:func:`~proxplan.planner.swarm.repair_stage.makespan_stage`, :mod:`proxplan.planner.swarm.makespan`), once, on the
   plan kept: the latest vehicle planned again together with the vehicles in its way, while that
   shortens the plan, within a count of plannings; never worse, always conflict-free. Not on the
   lattice plan (``SwarmOptions.makespan_repair``).

The caller (the pipeline) runs the independent verifier on the result as on every plan. The
:class:`~proxplan.planner.swarm.info.SwarmInfo` names the ``stage`` that produced the tracks
("straight", "prioritised" or "lattice"), the lower bound (largest straight-line rest-to-rest time
of any vehicle) and the makespans after each stage. The knobs of every stage are
:class:`~proxplan.planner.swarm.options.SwarmOptions`; a stage hands its tracks on as a
:class:`~proxplan.planner.swarm.stage.Stage`.

This module holds the entry points (:func:`swarm_timed`, :func:`swarm_again`); the stages live one
job per module, each importing only those below it: :mod:`~proxplan.planner.swarm.hand_on` (what a plan
hands on, planned again from it) -> :mod:`~proxplan.planner.swarm.stages` (the stages in order, and each
level of the stacked plan by them) -> :mod:`~proxplan.planner.swarm.repair_stage` (5) ->
:mod:`~proxplan.planner.swarm.retime_stage` (4); :mod:`~proxplan.planner.swarm.planned` (what the stages
give).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import replace

from proxplan.planfile import Scenario
from proxplan.planner.errors import PlanNotFound
from proxplan.planner.sampling.ordering import lower_bound_makespan_s
from proxplan.planner.swarm.enough import enough_bound_s
from proxplan.planner.swarm.frozen import apply_unfreezes, frozen_unmoved, moved_points, unfrozen_problem
from proxplan.planner.swarm.hand_on import handed_on, level_stacking, retimed_again
from proxplan.planner.swarm.info import SwarmHandOn, SwarmInfo
from proxplan.planner.swarm.options import SwarmOptions
from proxplan.planner.swarm.problem import swarm_applicable, swarm_problem
from proxplan.planner.swarm.retime_stage import HORIZON_MARGIN_S, retime_stage
from proxplan.planner.swarm.stages import level_options, plan_stages
from proxplan.planner.swarm.tracks import GRID_DT_S
from proxplan.planner.swarm.verify_guard import VerifyGuard
from proxplan.planner.timing.paths import TimedPath

SWARM_MIN_VEHICLES = 16  # formation changes with at least this many vehicles use the swarm layer by default

# names other modules import from here: the re-timing horizon's margin (refine_repair), and the
# stages benchmarks/why_128.py calls by their names before the split into modules (round 28B)
_stacking, _level_options, _retime_stage = level_stacking, level_options, retime_stage

__all__ = [
    "HORIZON_MARGIN_S",
    "SWARM_MIN_VEHICLES",
    "SwarmHandOn",
    "SwarmOptions",
    "swarm_again",
    "swarm_applicable",
    "swarm_timed",
]


def swarm_timed(
    scenario: Scenario,
    options: SwarmOptions | None = None,
    *,
    progress: Callable[[str, float], None] | None = None,
    deadline: float | None = None,
) -> tuple[dict[str, TimedPath], SwarmInfo]:
    """Timed paths of every vehicle and the :class:`SwarmInfo` (see module);
    :class:`~proxplan.planner.errors.PlanNotFound` when the coordination search stops on its budget
    or the ``deadline`` (time.perf_counter() value), or before it when the unfreeze step leaves a frozen pair
    (:func:`~proxplan.planner.swarm.frozen.frozen_unmoved`: no stage can plan it)."""
    opts = options or SwarmOptions()
    why = swarm_applicable(scenario)
    if why is not None:
        raise ValueError(f"the swarm layer cannot plan this scenario: {why}")
    t0 = time.perf_counter()
    original = swarm_problem(scenario, deflection_m=opts.deflection_m, tracking_bound=opts.tracking_bound)
    problem, unfreezes, frozen = unfrozen_problem(original)  # frozen pairs at the starts / goals (swarm.frozen)
    stuck = frozen_unmoved(problem)
    if stuck:  # no stage can plan a frozen pair: give up before the search instead of after its budget
        raise PlanNotFound(f"the swarm layer cannot plan {frozen}: no stage of it moves a frozen pair", vehicles=stuck)
    lower_bound = lower_bound_makespan_s(scenario)
    try:
        planned = plan_stages(
            problem,
            lower_bound,
            opts,
            scenario.assign_goals is not None,
            level_stacking(scenario, problem) if opts.levels else None,
            progress=progress,
            deadline=deadline,
            check=VerifyGuard(scenario, problem, original, unfreezes),
            enough_bound_s=enough_bound_s(scenario, problem, lower_bound),
        )
    except PlanNotFound as err:
        if not frozen:
            raise
        raise PlanNotFound(f"{err.message} ({frozen})", vehicles=err.vehicles, details=err.details) from err
    timed, info = handed_on(problem, lower_bound, opts, scenario.assign_goals is not None, planned, t0, (0, 0))
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
            return retimed_again(hand_on, options, progress=progress, deadline=deadline, check=check)
    if (options.deflection_m, options.tracking_bound) != (before.deflection_m, before.tracking_bound):
        return swarm_timed(scenario, options, progress=progress, deadline=deadline)
    t0 = time.perf_counter()
    problem = hand_on.problem
    memo = (problem.memo.hits, problem.memo.misses)
    planned = plan_stages(
        problem,
        hand_on.lower_bound_s,
        options,
        hand_on.assigned,
        level_stacking(scenario, problem) if options.levels else None,
        progress=progress,
        deadline=deadline,
        check=VerifyGuard(scenario, problem, problem, ()),
    )
    return handed_on(problem, hand_on.lower_bound_s, options, hand_on.assigned, planned, t0, memo)
