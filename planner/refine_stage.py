"""Stage 4 of the pipeline (:mod:`proxplan.planner.pipeline`): ``optimized`` refines the plan.

Outside the swarm layer the sampling plan is refined with CasADi one vehicle at a time
(:func:`proxplan.planner.optimizer.refine_plan`, a wall-clock budget); a plan it cannot improve is
kept, with a note. For swarms (the swarm layer ran): joint moves
(:func:`proxplan.planner.optimizer.joint_moves`, count budgets), or, where the plan is already within
``OPTIMAL_WITHIN`` of the lower bound, a note saying so.
"""

from __future__ import annotations

from collections.abc import Callable

from proxplan.planfile import Plan, Scenario
from proxplan.planner.swarm import SwarmInfo
from proxplan.planner.timing.plan_grid import moving_end_s

# ``optimized`` for swarms: a plan within OPTIMAL_WITHIN of the lower bound is not re-optimised
# (the must-show's 5 %); the others get joint moves (optimizer.joint_moves, count budgets)
OPTIMAL_WITHIN = 0.05


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
) -> Plan:
    """``plan`` refined where ``method`` is "optimized" (see module), else ``plan`` itself.
    ``time_budget_s``: the one-at-a-time optimiser's wall-clock budget (None: its default), s;
    ``swarm_ran``: the swarm layer ran for this scenario (then joint moves, whichever planner's plan
    this is); ``swarm_info``: what it reported (its lower bound), if anything."""
    if method != "optimized":
        return plan
    if swarm_ran:
        return _refine_swarm(scenario, plan, time_budget_s=time_budget_s, progress=progress, swarm_info=swarm_info)
    from proxplan.planner.optimizer import RefineOptions, refine_plan

    options = RefineOptions() if time_budget_s is None else RefineOptions(time_budget_s=time_budget_s)
    try:
        result = refine_plan(scenario, plan, seed=seed, progress=progress, options=options)
    except Exception as err:  # noqa: BLE001 - the optimiser must never lose the sampling plan
        first = str(err).splitlines()[0] if str(err) else ""
        plan.notes.append(f"optimized: refinement raised {type(err).__name__}: {first}; this is the sampling result")
        plan.method = "sampling (optimizer failed)"
        return plan
    if not result.success:
        plan.notes.append(f"optimized: refinement failed ({result.message}); this is the sampling result")
        plan.method = "sampling (optimizer fell back)"
        plan.solver = result.stats  # what IPOPT reported for the attempt that failed
        return plan
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
    return refined


def _refine_swarm(
    scenario: Scenario,
    plan: Plan,
    *,
    time_budget_s: float | None,
    progress: Callable[..., None] | None,
    swarm_info: SwarmInfo | None,
) -> Plan:
    """``optimized`` for swarms: joint moves (:func:`proxplan.planner.optimizer.joint_moves`): the
    vehicles that set the makespan, each with the vehicles in its way, optimised together with
    CasADi, all the others fixed as moving obstacles, within count budgets (``--time-budget`` does
    not apply); the verified shorter plan kept, else a note with the gap to the lower bound."""
    from proxplan.planner.optimizer import default_wrench_provider, joint_moves
    from proxplan.planner.optimizer.warm_problem import table_extent

    makespan = moving_end_s(plan)
    bound = float(plan.metrics.get("assignment_lower_bound_s") or (swarm_info.lower_bound_s if swarm_info else 0.0))
    if bound > 0.0 and makespan <= (1.0 + OPTIMAL_WITHIN) * bound:
        plan.notes.append(
            f"optimized: the swarm plan ({makespan:.2f} s) is within {100 * OPTIMAL_WITHIN:g} % of the lower bound "
            f"({bound:.2f} s); not re-optimised"
        )
        return plan
    if time_budget_s is not None:
        plan.notes.append("optimized: --time-budget does not apply to swarms (the joint moves have count budgets)")
    result = joint_moves(
        scenario, plan, wrench_provider=default_wrench_provider, extent_provider=table_extent, progress=progress
    )
    gap = f"{makespan / bound:.2f}x the lower bound {bound:.2f} s" if bound > 0.0 else "no lower bound"
    log = f" [{'; '.join(result.log)}]" if result.log else ""
    if not result.improved:
        plan.notes.append(f"optimized: {result.message} ({gap}){log}")
        return plan
    better = result.plan
    better.method = "optimized"
    better.verified = True  # joint_moves keeps only plans the verifier passed, this one included
    better.notes = list(plan.notes) + [f"optimized: {result.message}{log}"]
    return better
