"""Stage 4 of the pipeline (:mod:`proxplan.planner.pipeline`): ``optimized`` refines the plan.

Outside the swarm layer the sampling plan is refined with CasADi one vehicle at a time
(:func:`proxplan.planner.optimizer.refine_plan`, a wall-clock budget); a plan it cannot improve is
kept, with a note. For swarms (the swarm layer ran), where the plan is not already within
``OPTIMAL_WITHIN`` of the lower bound (then a note says so):

1. *the swarm layer's other plans* (:func:`_swarm_alternatives`): the swarm layer again with each
   option set of ``SWARM_ALTERNATIVES`` that the fast plan did not use, each a complete plan of its
   own (the plans it makes where prioritised planning gives up: the lattice plan and the stacked
   plan, types on levels of their own; re-timing that flies through waypoints); the shortest that
   passes ``verify`` replaces the fast plan (ties: the fast plan). Their budgets are the swarm
   layer's counts. Not planned again from the start: the fast plan's own tracks are re-timed
   through waypoints, and the give-up plans are planned on its problem
   (:func:`~proxplan.planner.swarm.plan.swarm_again`, the same tracks as planning afresh);
2. *the makespan repair, longer* (:func:`_repaired_longer`, :mod:`proxplan.planner.refine_repair`): rounds
   of re-timing through waypoints and the makespan repair on the kept plan's own tracks, kept only
   when shorter and verified;
3. *joint moves* (:func:`proxplan.planner.optimizer.joint_moves`, count budgets) on the plan kept.

Why 1: with fixed goals the vehicles that set the makespan fly long detours round a crowd in one
plane (grid-32: 6.9-7.8 m against 2.2-2.5 m straight, rest to rest through 5-6 corners, their goals
free seconds before they arrive), so no move of a few vehicles against all the others fixed brings
them in much earlier (docs/planner.md, stop 53 round 15C).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import replace

from proxplan.planfile import Plan, Scenario
from proxplan.planner.bounds import certified_bound
from proxplan.planner.errors import PlanNotFound
from proxplan.planner.swarm import SwarmInfo, SwarmOptions, swarm_timed
from proxplan.planner.swarm.plan import swarm_again
from proxplan.planner.timing.paths import TimedPath
from proxplan.planner.timing.plan_grid import assemble_plan, moving_end_s

# ``optimized`` for swarms: a plan within OPTIMAL_WITHIN of the lower bound is not re-optimised
# (the must-show's 5 %); the others get joint moves (optimizer.joint_moves, count budgets)
OPTIMAL_WITHIN = 0.05
# ``optimized`` for swarms: the swarm layer's other complete plans tried beside the fast one, (what it
# is, the SwarmOptions fields that make it). Chosen watching grid, circle, corridor and pillar at 32
# fixed goals (in-process, docs/planner.md stop 53 round 15C; against the fast plans 8.55, 6.20, 15.90,
# 8.40 s): the give-up plans 7.25 (stacked), 7.60 (stacked), 21.05 (lattice), 15.40 s (lattice);
# re-timing through waypoints 8.20, 6.20, 14.00, 8.20 s. Not watched: the randomised family.
# Since round 22S also the fast method's own re-timing passes (``--method swarm``: SwarmOptions' default;
# the pipeline adds OPTIMIZE_EXTRA_PASSES for ``optimized``, and the makespan repair after them then starts
# elsewhere: in-process at 32 fixed, 3 / 8 passes gave corridor 13.70 / 16.80 s, pillar 7.08 / 7.53 s,
# grid 8.10 / 7.55 s, circle 5.85 / 5.85 s), so that ``optimized`` is never longer than the fast plan.
SWARM_ALTERNATIVES: tuple[tuple[str, dict], ...] = (
    ("the plans made where prioritised planning gives up (lattice, stacked levels)", {"prioritized": False}),
    ("re-timing through waypoints", {"through_waypoints": "retime"}),
    ("the fast method's re-timing passes", {"passes": SwarmOptions().passes}),
)


def refine_stage(
    scenario: Scenario,
    plan: Plan,
    *,
    method: str,
    seed: int,
    time_budget_s: float | None,
    progress: Callable[..., None] | None,
    swarm_ran: bool,
    swarm_info: SwarmInfo | None,
    swarm_options: SwarmOptions | None = None,
    deadline: float | None = None,
) -> tuple[Plan, SwarmInfo | None]:
    """``plan`` refined where ``method`` is "optimized" (see module), else ``plan`` itself, and the
    :class:`SwarmInfo` of the swarm plan returned (``swarm_info`` unless another swarm plan replaced
    it). ``time_budget_s``: the one-at-a-time optimiser's wall-clock budget (None: its default), s;
    ``swarm_ran``: the swarm layer ran for this scenario (then joint moves, whichever planner's plan
    this is); ``swarm_info``: what it reported (its lower bound, its stage), if anything;
    ``swarm_options``: the options it planned with; ``deadline``: time.perf_counter() value after
    which no other swarm plan is tried."""
    if method != "optimized":
        return plan, swarm_info
    if swarm_ran:
        return _refine_swarm(
            scenario,
            plan,
            time_budget_s=time_budget_s,
            progress=progress,
            swarm_info=swarm_info,
            swarm_options=swarm_options or SwarmOptions(),
            deadline=deadline,
        )
    from proxplan.planner.optimizer import RefineOptions, refine_plan

    options = RefineOptions() if time_budget_s is None else RefineOptions(time_budget_s=time_budget_s)
    try:
        result = refine_plan(scenario, plan, seed=seed, progress=progress, options=options)
    except Exception as err:  # noqa: BLE001 - the optimiser must never lose the sampling plan
        first = str(err).splitlines()[0] if str(err) else ""
        plan.notes.append(f"optimized: refinement raised {type(err).__name__}: {first}; this is the sampling result")
        plan.method = "sampling (optimizer failed)"
        return plan, swarm_info
    if not result.success:
        plan.notes.append(f"optimized: refinement failed ({result.message}); this is the sampling result")
        plan.method = "sampling (optimizer fell back)"
        plan.solver = result.stats  # what IPOPT reported for the attempt that failed
        return plan, swarm_info
    refined = result.plan
    refined.method = "optimized"
    refined.notes = list(dict.fromkeys(list(plan.notes) + list(refined.notes or [])))  # keep order, once each
    for key in ("priority_order", "sampling_attempts"):
        refined.metrics.setdefault(key, plan.metrics.get(key))
    refined.metrics["optimizer_solve_time_s"] = result.solve_time_s
    refined.metrics["optimizer_iterations"] = result.iterations
    refined.solver = result.stats
    refined.scenario_file = plan.scenario_file
    refined.scenario_spec = plan.scenario_spec
    refined.verified = False  # refine_plan verified it, but against its own copy: the CLI checks again
    return refined, swarm_info


def _refine_swarm(
    scenario: Scenario,
    plan: Plan,
    *,
    time_budget_s: float | None,
    progress: Callable[..., None] | None,
    swarm_info: SwarmInfo | None,
    swarm_options: SwarmOptions,
    deadline: float | None,
) -> tuple[Plan, SwarmInfo | None]:
    """``optimized`` for swarms: the swarm layer's other plans (:func:`_swarm_alternatives`), then
    joint moves (:func:`proxplan.planner.optimizer.joint_moves`): the vehicles that set the makespan,
    each with the vehicles in its way, optimised together with CasADi, all the others fixed as moving
    obstacles, within count budgets (``--time-budget`` does not apply); the verified shorter plan
    kept, else a note with the gap to the lower bound."""
    from proxplan.planner.optimizer import default_wrench_provider, joint_moves
    from proxplan.planner.optimizer.warm_problem import table_extent

    makespan = moving_end_s(plan)
    # fixed goals: the certified bound (planner.bounds; the duration table's rounds up by 0.1-0.2 %, so it is
    # not strictly a lower bound); interchangeable goals: the assignment's
    assigned = plan.metrics.get("assignment_lower_bound_s")
    bound = float(assigned) if assigned else certified_bound(scenario).bound_s
    if bound > 0.0 and makespan <= (1.0 + OPTIMAL_WITHIN) * bound:
        plan.notes.append(
            f"optimized: the swarm plan ({makespan:.2f} s) is within {100 * OPTIMAL_WITHIN:g} % of the lower bound "
            f"({bound:.2f} s); not re-optimised"
        )
        return plan, swarm_info
    plan, swarm_info = _swarm_alternatives(scenario, plan, swarm_info, swarm_options, progress, deadline)
    longer = _repaired_longer(scenario, plan, swarm_info, progress, deadline)
    if longer is not plan and swarm_info is not None:  # the record says the kept plan's makespan, s
        swarm_info = replace(swarm_info, makespan_s=moving_end_s(longer))
    plan = longer
    makespan = moving_end_s(plan)
    if time_budget_s is not None:
        plan.notes.append("optimized: --time-budget does not apply to swarms (the joint moves have count budgets)")
    result = joint_moves(
        scenario, plan, wrench_provider=default_wrench_provider, extent_provider=table_extent, progress=progress
    )
    gap = f"{makespan / bound:.2f}x the lower bound {bound:.2f} s" if bound > 0.0 else "no lower bound"
    log = f" [{'; '.join(result.log)}]" if result.log else ""
    if not result.improved:
        plan.notes.append(f"optimized: {result.message} ({gap}){log}")
        return plan, swarm_info
    better = result.plan
    better.method = "optimized"
    better.verified = True  # joint_moves keeps only plans the verifier passed, this one included
    better.notes = list(plan.notes) + [f"optimized: {result.message}{log}"]
    return better, swarm_info


def _swarm_plan(
    scenario: Scenario,
    info: SwarmInfo | None,
    options: SwarmOptions,
    progress: Callable[..., None] | None,
    deadline: float | None,
) -> tuple[dict[str, TimedPath], SwarmInfo]:
    """The swarm layer's plan with ``options``: from what the fast plan handed on (its own tracks
    re-timed again, or other stages on its problem; :func:`~proxplan.planner.swarm.plan.swarm_again`)
    where it did, else planned afresh."""
    if info is not None and info.hand_on is not None:
        return swarm_again(scenario, info.hand_on, options, progress=progress, deadline=deadline)
    return swarm_timed(scenario, options, progress=progress, deadline=deadline)


def _swarm_alternatives(
    scenario: Scenario,
    plan: Plan,
    info: SwarmInfo | None,
    options: SwarmOptions,
    progress: Callable[..., None] | None,
    deadline: float | None,
) -> tuple[Plan, SwarmInfo | None]:
    """The shortest of ``plan`` (the fast swarm plan, or the sampling planner's) and the swarm
    layer's plans with each option set of ``SWARM_ALTERNATIVES`` the fast plan did not use (the
    give-up plans only where prioritised planning found the fast plan: else they were tried), each
    kept only when it passes ``verify``; with its :class:`SwarmInfo`, and a note per plan tried."""
    from proxplan.verify import verify_plan

    best, best_info, best_s = plan, info, moving_end_s(plan)
    if info is not None and info.hand_on is not None:
        options = info.hand_on.options  # the options of the attempt that gave the fast plan
    for what, fields in SWARM_ALTERNATIVES:
        if all(getattr(options, k) == v for k, v in fields.items()):
            continue  # the fast plan's own options
        if "prioritized" in fields and (info is None or info.stage != "prioritised"):
            continue  # prioritised planning gave up (the lattice or stacked plan is the fast one) or was not needed
        if deadline is not None and time.perf_counter() > deadline:
            plan.notes.append(f"optimized: {what} not tried (time budget spent)")
            break
        try:
            timed, other = _swarm_plan(scenario, info, replace(options, **fields), progress, deadline)
        except PlanNotFound as err:
            plan.notes.append(f"optimized: {what}: no plan ({err.message})")
            continue
        candidate = assemble_plan(scenario, timed, method="optimized", notes=[])
        got, bad = moving_end_s(candidate), verify_plan(candidate, scenario)
        said = f"optimized: {what}: {got:.2f} s ({other.stage}{', failed verify: ' + str(bad[0]) if bad else ''})"
        if bad or got >= best_s - 1e-9:
            plan.notes.append(said + f", not shorter than {best_s:.2f} s" if not bad else said)
            continue
        plan.notes.append(said + f", shorter than {best_s:.2f} s: kept ({other.coordination})")
        best, best_info, best_s = candidate, other, got
    if best is not plan:
        best.notes = list(plan.notes)
        best.method = "optimized"
        best.verified = True  # verify_plan passed it above
        best.scenario_file, best.scenario_spec = plan.scenario_file, plan.scenario_spec
    return best, best_info


def _repaired_longer(
    scenario: Scenario,
    plan: Plan,
    info: SwarmInfo | None,
    progress: Callable[..., None] | None,
    deadline: float | None,
) -> Plan:
    """``plan`` after the longer makespan repair (:func:`proxplan.planner.refine_repair.longer_repair`) of the
    swarm plan's own tracks (``info.hand_on.tracks``), where it is shorter and passes ``verify``; else
    ``plan``; a note either way. Not where the plan is not the swarm layer's (no tracks handed on) or its
    starts or goals were moved by an unfreeze step (the tracks are not the whole plan, swarm.frozen)."""
    from proxplan.planner.refine_repair import longer_repair
    from proxplan.planner.swarm.frozen import moved_points
    from proxplan.verify import verify_plan

    hand_on = None if info is None else info.hand_on
    if hand_on is None or hand_on.tracks is None:
        plan.notes.append("optimized: the makespan repair, longer: not run (not the swarm layer's tracks)")
        return plan
    if moved_points(scenario, hand_on.problem):
        plan.notes.append("optimized: the makespan repair, longer: not run (starts or goals moved by an unfreeze)")
        return plan
    if progress:
        progress("optimized: the makespan repair, longer", 0.92)
    problem = hand_on.problem
    got = longer_repair(problem, hand_on.tracks, deadline=deadline)
    said = f"optimized: the makespan repair, longer: {'; '.join(got.rounds)}"
    best_s = moving_end_s(plan)
    if got.makespan_after_s >= got.makespan_before_s - 1e-9:
        plan.notes.append(said + "; nothing shorter")
        return plan
    timed = {problem.names[a]: got.tracks[a].timed_path() for a in range(problem.n_agents)}
    candidate = assemble_plan(scenario, timed, method="optimized", notes=[])
    new_s, bad = moving_end_s(candidate), verify_plan(candidate, scenario)
    if bad or new_s >= best_s - 1e-9:
        why = f"failed verify: {bad[0]}" if bad else f"not shorter than {best_s:.2f} s"
        plan.notes.append(f"{said}; {new_s:.2f} s {why}")
        return plan
    candidate.notes = list(plan.notes) + [f"{said}; {new_s:.2f} s, shorter than {best_s:.2f} s: kept"]
    candidate.verified = True  # verify_plan passed it above
    candidate.scenario_file, candidate.scenario_spec = plan.scenario_file, plan.scenario_spec
    return candidate
