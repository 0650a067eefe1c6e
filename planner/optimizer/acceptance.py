"""Taking an optimiser solution back into a plan and judging it: the solution sampled exactly on the
plan grid (uniformly slowed while only kinematic limits break between nodes), the independent
verifier, the comparison with the initial plan (makespan, then peak authority usage) and the warm
start about a solution for a second pass."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from proxplan.planner.optimizer.ocp import sample_solution
from proxplan.planner.optimizer.ocp_problem import OcpProblem, OcpSolution
from proxplan.planner.optimizer.options import RefineOptions
from proxplan.planner.timing.plan_grid import moving_end_s

_KINEMATIC_KINDS = ("speed", "accel", "jerk", "velocity", "acceleration")


def peak_usage(plan, scenario) -> float:
    """Largest authority usage of any vehicle along ``plan`` (model evaluated directly), -."""
    from proxplan.verify import wrench_along_plan

    along = wrench_along_plan(plan, scenario, t_s=plan.t_s)
    return max([float(a.usage.max()) for a in along.values() if a.usage.size] + [0.0])


def is_better(plan, initial_plan, scenario) -> tuple[bool, str]:
    """(whether ``plan`` beats ``initial_plan``: shorter makespan, or at equal makespan (within
    1e-6 s) a lower peak authority usage; why not)."""
    end, end0 = moving_end_s(plan), moving_end_s(initial_plan)
    if end < end0 - 1e-6:
        return True, ""
    if end > end0 + 1e-6:
        return False, f"optimised plan was slower ({end:.2f} s > {end0:.2f} s)"
    u, u0 = peak_usage(plan, scenario), peak_usage(initial_plan, scenario)
    if u < u0 - 1e-6:
        return True, ""
    return (
        False,
        f"optimised plan was not faster ({end:.2f} s) and its peak authority usage not lower ({u:.3f} >= {u0:.3f})",
    )


def solution_to_plan(solution: OcpSolution, scenario, initial_plan, *, time_scale: float = 1.0):
    """Sample ``solution`` on the plan grid (step ``initial_plan.dt_s``), rounding the duration up to
    a whole number of steps by a uniform slow-down. Returns a Plan (method "optimized")."""
    from proxplan.planfile import Plan, VehicleTrajectory

    dt = float(initial_plan.dt_s)
    duration = solution.duration_s * time_scale
    steps = max(1, math.ceil(duration / dt - 1e-6))
    scale = steps * dt / solution.duration_s
    t = np.arange(steps + 1) * dt
    sampled = sample_solution(solution, t, time_scale=scale)
    vehicles = {}
    for name, task in scenario.vehicles.items():
        p, v, a = sampled[name]
        vehicles[name] = VehicleTrajectory(name, task.type_name, task.vehicle, t, p, v, a)
    return Plan(
        scenario=initial_plan.scenario,
        dt_s=dt,
        vehicles=vehicles,
        metrics=dict(initial_plan.metrics),
        method="optimized",
        notes=list(initial_plan.notes),
        scenario_file=initial_plan.scenario_file,
        scenario_spec=initial_plan.scenario_spec,
    )


def _verify(plan, scenario) -> list:
    from proxplan.verify import verify_plan

    return list(verify_plan(plan, scenario))


def describe(violations: list) -> str:
    v = violations[0]
    more = f" (+{len(violations) - 1} more)" if len(violations) > 1 else ""
    return f"{getattr(v, 'vehicle', '?')} {getattr(v, 'kind', '?')} at t={getattr(v, 't_s', float('nan')):.2f} s: {getattr(v, 'detail', '')}{more}"


def sample_and_verify(solution: OcpSolution, scenario, initial_plan, options: RefineOptions):
    """(plan, violations, time scale): the solution on the plan grid, slowed uniformly in 5 % steps
    (up to ``options.max_slowdown``) while the only violations are kinematic ones between nodes."""
    scale = 1.0
    while True:
        plan = solution_to_plan(solution, scenario, initial_plan, time_scale=scale)
        violations = _verify(plan, scenario)
        kinematic = [v for v in violations if any(k in str(getattr(v, "kind", "")) for k in _KINEMATIC_KINDS)]
        if not violations or len(kinematic) < len(violations) or scale * 1.05 > options.max_slowdown:
            return plan, violations, scale
        scale *= 1.05


def rewarm(problem: OcpProblem, solution: OcpSolution) -> OcpProblem:
    """``problem`` warm-started (and pruned) about ``solution`` instead of the sampling plan."""
    agents = tuple(
        replace(
            a,
            warm_position_m=solution.position_m[a.name],
            warm_velocity_mps=solution.velocity_mps[a.name],
            warm_acceleration_mps2=solution.acceleration_mps2[a.name],
        )
        if a.moving
        else a
        for a in problem.agents
    )
    return replace(problem, agents=agents, warm_duration_s=solution.duration_s)
