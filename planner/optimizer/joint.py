"""The joint problem: all moving vehicles of a scenario optimised together
(:mod:`proxplan.planner.optimizer.ocp`), with an exact-table retry for small problems, a second
pass after a failed verification and the verified, better plan or the reason why not."""

from __future__ import annotations

import time
from dataclasses import replace

from proxplan.planfile import SolverStats
from proxplan.planner.optimizer.acceptance import describe, is_better, rewarm, sample_and_verify
from proxplan.planner.optimizer.ocp import build_and_solve
from proxplan.planner.optimizer.ocp_problem import OcpSolution
from proxplan.planner.optimizer.options import RefineOptions, RefineResult
from proxplan.planner.optimizer.warm_problem import build_problem
from proxplan.planner.timing.plan_grid import moving_end_s


def joint_refine(scenario, initial_plan, options: RefineOptions, wrench_provider, progress) -> RefineResult:
    """The joint problem of all moving vehicles (:mod:`proxplan.planner.optimizer.ocp`)."""
    problem = build_problem(scenario, initial_plan, options=options, wrench_provider=wrench_provider)

    def accept(candidate: OcpSolution) -> bool:
        return not sample_and_verify(candidate, scenario, initial_plan, options)[1]

    solution = build_and_solve(problem, progress=progress, accept=accept if options.stop_when_verified else None)
    solve_time, iterations, passes, solves = solution.solve_time_s, solution.iterations, 1, solution.rounds

    def stats(converged: bool) -> SolverStats:
        return SolverStats(
            method="joint",
            converged=converged,
            return_status=solution.status,
            iterations=iterations,
            solves=solves,
            solve_time_s=solve_time,
            constraint_violation=solution.constraint_violation,
            objective=solution.objective,
        )

    small = problem.n_intervals * sum(a.moving for a in problem.agents) <= options.exact_retry_node_vehicles
    t_start = time.perf_counter() - solution.solve_time_s - solution.build_time_s

    def budget_left() -> bool:
        return time.perf_counter() - t_start < options.time_budget_s

    if not solution.success and small and budget_left():
        # small problem: retry with the exact (MX) wrench table instead of its linearisation
        if progress is not None:
            progress(f"optimiser: linearised solve failed ({solution.status}); retrying with the exact table")
        solution = build_and_solve(replace(problem, linearize=False), progress=progress)
        solve_time += solution.solve_time_s
        iterations += solution.iterations
        solves += solution.rounds
    if not solution.success:
        return RefineResult(
            initial_plan,
            False,
            f"optimiser did not converge (IPOPT: {solution.status} after {solution.iterations} iterations, "
            f"{solution.solve_time_s:.2f} s); kept the sampling plan",
            solve_time,
            iterations,
            stats(False),
        )
    plan, violations, scale = sample_and_verify(solution, scenario, initial_plan, options)
    if violations and budget_left():
        if problem.interaction_extent:
            # the optimiser moved vehicles into interactions the warm start did not have (relative
            # timing changed): one more pass, pruned and warm-started about the first solution
            retry = rewarm(problem, solution)
        else:
            # a breach between check points: once more from the same warm start with wider
            # margins (chord margin x 3, authority bound 0.1 lower)
            retry = replace(
                problem,
                chord_margin_m=3.0 * problem.chord_margin_m,
                authority_margin=max(0.5, problem.authority_margin - 0.1),
            )
        if progress is not None:
            progress(f"optimiser: second pass ({describe(violations)})")
        second = build_and_solve(retry, progress=progress)
        solve_time += second.solve_time_s
        iterations += second.iterations
        solves += second.rounds
        if second.success:
            solution, passes = second, 2
            plan, violations, scale = sample_and_verify(solution, scenario, initial_plan, options)
    if violations:
        return RefineResult(
            initial_plan,
            False,
            f"optimised plan failed verification ({describe(violations)}); kept the sampling plan",
            solve_time,
            iterations,
            stats(False),
        )
    better, why = is_better(plan, initial_plan, scenario)
    if not better:
        return RefineResult(initial_plan, False, f"{why}; kept the sampling plan", solve_time, iterations, stats(False))
    note = (
        f"optimized: CasADi/IPOPT {solution.status} in {iterations} iterations, "
        f"{solve_time:.2f} s solve ({passes} pass{'es' if passes > 1 else ''}, "
        f"{problem.n_intervals} intervals); makespan {moving_end_s(initial_plan):.2f} s -> {moving_end_s(plan):.2f} s, verified"
        + (f"; slowed x{scale:.2f} to keep kinematic limits between nodes" if scale > 1.0 else "")
    )
    plan = replace(plan, notes=list(plan.notes) + [note])
    plan.metrics["optimizer_solve_time_s"] = solve_time
    plan.metrics["optimizer_iterations"] = iterations
    plan.metrics["makespan_s"] = plan.makespan_s
    plan.solver = stats(True)
    return RefineResult(plan, True, note, solve_time, iterations, plan.solver)
