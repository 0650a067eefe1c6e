"""Refine a sampling plan with the CasADi optimiser (:mod:`proxplan.planner.optimizer.ocp`) into a tighter plan.

``refine_plan(scenario, initial_plan)`` warm-starts the joint optimal-control problem from the
sampling planner's result, solves it with IPOPT, samples the piecewise-constant-jerk solution
exactly on the plan's time grid (``dt_s``; the optimised duration is rounded up to a whole number of
steps by a uniform slow-down, which keeps every limit), and re-checks the result with
``proxplan.verify.checks.verify_plan`` (the model evaluated directly, not the table). A failed solve or a
refined plan that fails the check returns the initial plan with ``success=False`` and a message
saying why; the caller never gets a silently worse plan.

The solution is already a jerk-limited time parameterisation, so no Ruckig pass is needed for it;
if the dense check finds a speed/acceleration/jerk breach between grid nodes, the whole plan is
slowed uniformly (factor s: v / s, a / s^2, j / s^3) until it holds.

``seed`` is accepted for API symmetry with the sampling planner; IPOPT is deterministic.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import replace

from proxplan.planfile import SolverStats
from proxplan.planner.optimizer.joint import joint_refine
from proxplan.planner.optimizer.options import RefineOptions, RefineResult, WrenchProvider
from proxplan.planner.optimizer.warm_problem import default_wrench_provider, table_extent
from proxplan.planner.timing.plan_grid import moving_end_s


def check_final_configuration(scenario) -> None:
    """Raise ``proxplan.planner.errors.InfeasibleError`` when the final configuration itself (every vehicle
    at rest at its goal / hover point / dock) needs more than ``limits.authority_fraction`` of some
    vehicle's authority: then no trajectory can satisfy the limit (model evaluated directly)."""
    from proxplan.costmaps import sources_wrench
    from proxplan.physics import authority_usage
    from proxplan.planner.errors import InfeasibleError

    options = scenario.model_options
    final = {n: scenario.final_position_m(n) for n in scenario.vehicles}
    fraction = scenario.limits.authority_fraction
    for nt, tgt in scenario.vehicles.items():
        above = [ns for ns in scenario.vehicles if ns != nt and (final[nt] - final[ns])[2] < -1e-6]
        if not above:
            continue
        worst = above[0]
        sources = [(scenario.vehicles[ns].vehicle, (final[nt] - final[ns])[None, :]) for ns in above]
        # every source above at once (a stack shields, proxplan.physics.stack), as the verifier
        force, torque = sources_wrench(tgt.vehicle, sources, options, getattr(scenario, "effects", ()))
        usage = float(authority_usage(tgt.vehicle, force, torque)[0])
        if usage > fraction:
            raise InfeasibleError(
                nt,
                "authority",
                f"vehicle {nt!r}: at its final position it needs {usage:.3f} of its authority in the "
                f"downwash of {worst!r}, more than limits.authority_fraction = {fraction:g}; no plan can "
                f"meet that limit (raise authority_fraction or change the dock offset / goals)",
            )


def refine_plan(
    scenario,
    initial_plan,
    *,
    seed: int = 0,
    progress: Callable[[str], None] | None = None,
    options: RefineOptions = RefineOptions(),
    wrench_provider: WrenchProvider | None = None,
) -> RefineResult:
    """Optimise ``initial_plan`` (a Plan of ``scenario``) within ``options.time_budget_s``.

    Up to ``options.max_joint_vehicles`` moving vehicles (or any dock): the joint problem of all of
    them (:mod:`proxplan.planner.optimizer.ocp`), then, if it fails and there is no dock, the decomposed optimisation
    (:mod:`proxplan.planner.optimizer.reoptimize`) with the rest of the budget. More: the decomposed optimisation. Returns a :class:`RefineResult`; the plan it
    returns with ``success`` passed the verifier and is better than ``initial_plan`` (shorter
    makespan, or lower peak authority usage at equal makespan). On any failure its ``plan`` is
    ``initial_plan`` unchanged and ``success`` is False with the reason in ``message``.
    """
    del seed  # IPOPT is deterministic
    if not options.time_budget_s > 0:
        from proxplan.fileio import UserError

        raise UserError(f"--time-budget: expected a positive number of seconds, got {options.time_budget_s:g}")
    check_final_configuration(scenario)
    if not any(not t.hover for t in scenario.vehicles.values()):
        return RefineResult(initial_plan, True, "nothing moves; plan kept", 0.0, 0)
    t0 = time.perf_counter()
    n_moving = sum(not t.hover for t in scenario.vehicles.values())
    has_docks = any(t.dock_with is not None for t in scenario.vehicles.values())
    if has_docks or n_moving <= options.max_joint_vehicles:  # the joint problem
        joint_options = replace(options, max_cpu_time_s=min(options.max_cpu_time_s, options.time_budget_s))
        joint = joint_refine(scenario, initial_plan, joint_options, wrench_provider, progress)
        remaining = options.time_budget_s - (time.perf_counter() - t0)
        if joint.success or has_docks or remaining < 1.0:
            return joint
        # it failed: the decomposition with what is left of the budget
        budget = replace(options, time_budget_s=remaining)
        dec = _decomposed(scenario, initial_plan, budget, wrench_provider, progress)
        if dec.success:
            notes = list(dec.plan.notes) + [f"joint problem: {joint.message}"]
            return replace(dec, plan=replace(dec.plan, notes=notes))
        return replace(dec, message=f"{joint.message}; then {dec.message}")
    return _decomposed(scenario, initial_plan, options, wrench_provider, progress)


def _decomposed(scenario, initial_plan, options: RefineOptions, wrench_provider, progress) -> RefineResult:
    """Many vehicles: :func:`proxplan.planner.optimizer.reoptimize.reoptimize_plan` (one vehicle at a time against the
    others' fixed trajectories, sparse pairs) within ``options.time_budget_s``."""
    from proxplan.planner.optimizer.reoptimize import ReoptOptions, reoptimize_plan

    result = reoptimize_plan(
        scenario,
        initial_plan,
        wrench_provider=wrench_provider or default_wrench_provider,
        extent_provider=None if wrench_provider is not None else table_extent,
        options=ReoptOptions(time_budget_s=options.time_budget_s, weights=options.weights),
        progress=progress,
    )
    stats = SolverStats(
        method="decomposed",
        converged=result.improved,
        return_status=result.last_status,
        iterations=result.iterations,
        solves=result.solves,
        solve_time_s=result.solve_time_s,
        constraint_violation=result.max_violation,
        objective=float("nan"),  # one objective per vehicle solve; no single value
    )
    if not result.improved:
        return RefineResult(
            initial_plan,
            False,
            result.message + "; kept the sampling plan",
            result.solve_time_s,
            result.iterations,
            stats,
        )
    plan = result.plan
    plan = replace(plan, method="optimized", notes=list(plan.notes) + [f"optimized: {result.message}"])
    plan.metrics["optimizer_solve_time_s"] = result.solve_time_s
    plan.metrics["optimizer_iterations"] = result.iterations
    plan.metrics["optimizer_solves"] = result.solves
    plan.metrics["sampling_makespan_s"] = moving_end_s(initial_plan)
    plan.metrics["makespan_s"] = moving_end_s(plan)
    plan.solver = stats
    return RefineResult(plan, True, result.message, result.solve_time_s, result.iterations, stats)
