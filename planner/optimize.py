"""Refine a sampling plan with the CasADi optimiser (:mod:`proxplan.planner.ocp`) into a tighter plan.

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

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from proxplan.planfile import Plan, SolverStats
from proxplan.planner.ocp import build_and_solve, sample_solution
from proxplan.planner.ocp_problem import OcpAgent, OcpProblem, OcpSolution, OcpWeights, scenario_fields

WrenchProvider = (
    Callable  # (source Vehicle, target Vehicle, scenario) -> casadi.Function offset_m -> (F_z, tau_x, tau_y)
)


@dataclass(frozen=True)
class RefineResult:
    """Result of :func:`refine_plan`: the plan to use (refined, or the initial one on failure)."""

    plan: Plan
    success: bool
    message: str
    solve_time_s: float  # IPOPT wall time, s
    iterations: int  # IPOPT iterations
    stats: SolverStats | None = None  # IPOPT statistics of the solve (stored in plan.json as ``solver``)


@dataclass(frozen=True)
class RefineOptions:
    """Tuning of the refinement; the defaults are the product's."""

    interval_s: float = 0.2  # target grid step of the OCP, s
    min_intervals: int = 20
    max_intervals: int = 80
    max_node_vehicles: int = 160  # cap on n_intervals x moving vehicles
    # keep authority terms only where the warm start is within the wrench table's lateral extent
    # (+ 0.5 m), with a second pass about the first solution; faster, but on the 8-vehicle swap
    # the relative timing moves enough that the result failed verification, so it is off
    prune_by_table_extent: bool = False
    # stop re-linearising as soon as a round passes the verifier: faster (swap of 8: 5.0 s instead of
    # 8.4 s of IPOPT) but later rounds tighten the plan (makespan 7.10 s after one round, 5.95 s after four)
    stop_when_verified: bool = False
    exact_retry_node_vehicles: int = 60  # retry a failed solve with the exact MX table up to this size
    weights: OcpWeights = OcpWeights()
    max_cpu_time_s: float = 30.0  # IPOPT time limit per solve and wall budget of the rounds, s
    max_iterations: int = 600  # IPOPT iterations per solve
    max_slowdown: float = 1.3  # largest uniform slow-down accepted to repair a kinematic breach, -
    # wall-clock budget of the whole refinement, s (plan --time-budget); the best verified plan
    # found by then is returned
    time_budget_s: float = 60.0
    # up to max_joint_vehicles moving vehicles (or any dock): the joint problem, and if it fails (no
    # docks) the decomposed optimisation (proxplan.planner.reoptimize: one vehicle at a time, sparse pairs)
    # with the rest of the budget; more: decomposed only (on the swap of 8 it found 4.10 s where
    # the joint problem found 5.95 s, and the joint problem of 8 formation vehicles did not converge)
    max_joint_vehicles: int = 4


def default_wrench_provider(source, target, scenario):
    """The differentiable wrench table of the cost maps (same numbers as proxplan.physics.disturbance)."""
    from proxplan.costmaps import pair_maps
    from proxplan.physics import ModelOptions

    form = getattr(scenario, "field_form", None)
    options = ModelOptions(field_form=form) if form else ModelOptions()
    effects = getattr(scenario, "effects", ())
    return pair_maps(source, target, options=options, effects=effects).table.casadi_function()


def _table_extent(source, target, scenario):
    """dz_m -> lateral half-width (m) of the pair's wrench table (zero beyond it)."""
    from proxplan.costmaps import pair_maps
    from proxplan.physics import ModelOptions

    form = getattr(scenario, "field_form", None)
    options = ModelOptions(field_form=form) if form else ModelOptions()
    effects = getattr(scenario, "effects", ())
    return pair_maps(source, target, options=options, effects=effects).table.scale.half_width_m


def moving_end_s(plan) -> float:
    """Time after which no vehicle of ``plan`` moves any more (the makespan of DESIGN.md), s."""
    end = 0.0
    for tr in plan.vehicles.values():
        moving = np.flatnonzero(np.linalg.norm(tr.velocity_mps, axis=1) > 1e-4)
        if moving.size:
            end = max(end, float(tr.t_s[min(moving[-1] + 1, tr.t_s.size - 1)]))
    return end


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


APPROACH_BAND_M = 0.04  # lateral band around the dock axis over which the approach usage is maximised, m
APPROACH_DZ_SAMPLES = 80  # dz samples of the approach usage envelope


def approach_usage_function(source, target, scenario, dz_max_m: float):
    """casadi Function dz_m -> the largest authority usage of ``target`` (-) at vertical distance
    dz below ``source`` (0 < dz <= dz_max_m) within ``APPROACH_BAND_M`` of the source's axis: the
    model evaluated directly (``proxplan.costmaps.pair_wrench``, base model and the scenario's
    effects; inside the invalid zone, dz < 3 L, its extrapolated near field), as the verifier
    evaluates a dock pair on its final approach. Piecewise linear in dz (``casadi.pw_lin``, SX)."""
    import casadi as ca

    from proxplan.costmaps import pair_wrench
    from proxplan.physics import ModelOptions, authority_usage

    form = getattr(scenario, "field_form", None)
    options = ModelOptions(field_form=form) if form else ModelOptions()
    dz = np.linspace(1e-3, dz_max_m, APPROACH_DZ_SAMPLES)
    radii = np.linspace(0.0, APPROACH_BAND_M, 9)
    angles = np.linspace(0.0, np.pi / 2, 7)  # X-frame target: symmetric under x -> -x, y -> -y
    rr, aa, zz = np.meshgrid(radii, angles, dz, indexing="ij")
    offsets = np.column_stack([(rr * np.cos(aa)).ravel(), (rr * np.sin(aa)).ravel(), -zz.ravel()])
    force, torque = pair_wrench(source, target, offsets, options, getattr(scenario, "effects", ()))
    usage = authority_usage(target, force, torque).reshape(rr.shape).max(axis=(0, 1))  # (K,)
    x = ca.SX.sym("dz_m")
    return ca.Function("approach_usage", [x], [ca.pw_lin(x, ca.DM(dz), ca.DM(usage))])


APPROACH_TOLERANCE_M = 0.01  # the warm start is "on its final approach" this close to the A-D segment, m


def approach_start_s(scenario, plan) -> float | None:
    """Time (s) from which every docking vehicle of ``plan`` stays on its final approach (within
    ``APPROACH_TOLERANCE_M`` of the segment from its approach point A to its dock point D, both
    relative to the dock partner's current position, as the verifier's dock exemption); None
    without docks."""
    starts = []
    t = np.asarray(plan.t_s, float)
    for name, task in scenario.vehicles.items():
        if task.dock_with is None:
            continue
        a_pt, d_pt = scenario.dock_geometry(name)
        base = scenario.final_position_m(task.dock_with)
        a_rel, d_rel = a_pt - base, d_pt - base
        rel = plan.vehicles[name].position_m - plan.vehicles[task.dock_with].position_m
        seg = a_rel - d_rel
        f = np.clip((rel - d_rel) @ seg / max(float(seg @ seg), 1e-12), 0.0, 1.0)
        off_segment = np.linalg.norm(rel - (d_rel + f[:, None] * seg), axis=1) > APPROACH_TOLERANCE_M
        last_off = np.flatnonzero(off_segment)
        starts.append(float(t[last_off[-1] + 1]) if last_off.size and last_off[-1] + 1 < t.size else float(t[0]))
    return max(starts) if starts else None


def _n_intervals(makespan_s: float, n_moving: int, options: RefineOptions) -> int:
    """Grid size: one interval per ``interval_s`` of the warm start, capped so that the joint
    problem keeps about ``max_node_vehicles`` vehicle-nodes (IPOPT time grows fast beyond)."""
    cap = max(options.min_intervals, min(options.max_intervals, options.max_node_vehicles // max(1, n_moving)))
    return int(np.clip(math.ceil(makespan_s / options.interval_s), options.min_intervals, cap))


def build_problem(
    scenario, initial_plan, *, options: RefineOptions = RefineOptions(), wrench_provider: WrenchProvider | None = None
) -> OcpProblem:
    """The :class:`proxplan.planner.ocp.OcpProblem` of ``scenario`` warm-started from ``initial_plan``."""
    provider = wrench_provider or default_wrench_provider
    T0 = moving_end_s(initial_plan) or float(initial_plan.makespan_s)
    n = _n_intervals(T0, sum(not t.hover for t in scenario.vehicles.values()), options)
    t_nodes = np.linspace(0.0, T0, n + 1)
    n_approach = 0
    t_approach = approach_start_s(scenario, initial_plan)
    if t_approach is not None and 0.0 < t_approach < T0:
        # docking: the last intervals are the final-approach phase (its own free duration)
        n_approach = int(np.clip(math.ceil((T0 - t_approach) / options.interval_s), 3, max(3, n // 3)))
        t_nodes = np.concatenate(
            [np.linspace(0.0, t_approach, n - n_approach + 1), np.linspace(t_approach, T0, n_approach + 1)[1:]]
        )
    # the sampling plan flies at 100 % of the kinematic limits (Ruckig), the OCP keeps a margin
    # (OcpProblem.kinematic_margin): the warm start is the same paths slowed uniformly by
    # 1 / margin (speed x m, acceleration x m^2, jerk x m^3), which is feasible for every limit
    stretch = 1.0 / OcpProblem.kinematic_margin
    agents = []
    for name, task in scenario.vehicles.items():
        moving = not task.hover
        warm = initial_plan.vehicles[name].sample(t_nodes) if moving else (None, None, None)
        radius = float(task.body_radius_m)
        reach = 0.0
        if task.dock_with is not None:
            from proxplan.verify import GOAL_TOLERANCE_M

            approach, dock = scenario.dock_geometry(name)
            approach_m = float(np.linalg.norm(approach - dock))
            reach = approach_m + GOAL_TOLERANCE_M - 0.02
        agents.append(
            OcpAgent(
                name=name,
                vehicle=task.vehicle,
                moving=moving,
                start_m=np.asarray(task.start_m, float),
                goal_m=None if task.goal_m is None else np.asarray(task.goal_m, float),
                dock_with=task.dock_with,
                dock_offset_m=None if task.dock_offset_m is None else np.asarray(task.dock_offset_m, float),
                dock_reach_m=reach,
                dock_approach_m=approach_m if task.dock_with is not None else 0.0,
                max_speed_mps=task.max_speed_mps,
                max_accel_mps2=task.max_accel_mps2,
                max_jerk_mps3=task.max_jerk_mps3,
                body_radius_m=radius,
                warm_position_m=warm[0],
                warm_velocity_mps=None if warm[1] is None else warm[1] / stretch,
                warm_acceleration_mps2=None if warm[2] is None else warm[2] / stretch**2,
            )
        )
    cache: dict[tuple[int, int], object] = {}
    extents: dict[tuple[str, str], Callable] = {}
    wrench = {}
    tasks = scenario.vehicles
    for ns, src in tasks.items():
        for nt, tgt in tasks.items():
            if ns == nt or (src.hover and tgt.hover):
                continue
            key = (id(src.vehicle), id(tgt.vehicle))
            if key not in cache:
                cache[key] = provider(src.vehicle, tgt.vehicle, scenario)
            wrench[(ns, nt)] = cache[key]
            if wrench_provider is None and options.prune_by_table_extent:  # table is zero beyond it
                extents[(ns, nt)] = _table_extent(src.vehicle, tgt.vehicle, scenario)
    dock_usage = {}
    for name, task in tasks.items():
        if task.dock_with is None or task.dock_offset_m is None:
            continue
        approach, dock = scenario.dock_geometry(name)
        partner_end = scenario.final_position_m(task.dock_with)
        dz_end, dz_start = float(dock[2] - partner_end[2]), float(approach[2] - partner_end[2])
        if abs(dz_end) < 1e-6 and abs(dz_start) < 1e-6:
            continue  # a level dock: no downwash between the pair on its approach
        upper, lower = (name, task.dock_with) if dz_end > 0 else (task.dock_with, name)
        dz_max = max(abs(dz_end), abs(dz_start)) + APPROACH_BAND_M + 0.1
        dock_usage[(upper, lower)] = approach_usage_function(
            tasks[upper].vehicle, tasks[lower].vehicle, scenario, dz_max
        )
    return OcpProblem(
        agents=tuple(agents),
        n_intervals=n,
        warm_duration_s=T0 * stretch,
        max_duration_s=T0 * stretch,
        warm_node_times_s=t_nodes * stretch,
        approach_intervals=n_approach,
        dock_usage_functions=dock_usage if wrench_provider is None else {},
        **scenario_fields(scenario),
        wrench_functions=wrench,
        interaction_extent=extents,
        weights=options.weights,
        max_cpu_time_s=options.max_cpu_time_s,
        max_iterations=options.max_iterations,
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


_KINEMATIC_KINDS = ("speed", "accel", "jerk", "velocity", "acceleration")


def _verify(plan, scenario) -> list:
    from proxplan.verify import verify_plan

    return list(verify_plan(plan, scenario))


def _describe(violations: list) -> str:
    v = violations[0]
    more = f" (+{len(violations) - 1} more)" if len(violations) > 1 else ""
    return f"{getattr(v, 'vehicle', '?')} {getattr(v, 'kind', '?')} at t={getattr(v, 't_s', float('nan')):.2f} s: {getattr(v, 'detail', '')}{more}"


def _sample_and_verify(solution: OcpSolution, scenario, initial_plan, options: RefineOptions):
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
    them (:mod:`proxplan.planner.ocp`), then, if it fails and there is no dock, the decomposed optimisation
    (:mod:`proxplan.planner.reoptimize`) with the rest of the budget. More: the decomposed optimisation. Returns a :class:`RefineResult`; the plan it
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
        joint = _joint(scenario, initial_plan, joint_options, wrench_provider, progress)
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


def _joint(scenario, initial_plan, options: RefineOptions, wrench_provider, progress) -> RefineResult:
    """The joint problem of all moving vehicles (:mod:`proxplan.planner.ocp`)."""
    problem = build_problem(scenario, initial_plan, options=options, wrench_provider=wrench_provider)

    def accept(candidate: OcpSolution) -> bool:
        return not _sample_and_verify(candidate, scenario, initial_plan, options)[1]

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
    plan, violations, scale = _sample_and_verify(solution, scenario, initial_plan, options)
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
            progress(f"optimiser: second pass ({_describe(violations)})")
        second = build_and_solve(retry, progress=progress)
        solve_time += second.solve_time_s
        iterations += second.iterations
        solves += second.rounds
        if second.success:
            solution, passes = second, 2
            plan, violations, scale = _sample_and_verify(solution, scenario, initial_plan, options)
    if violations:
        return RefineResult(
            initial_plan,
            False,
            f"optimised plan failed verification ({_describe(violations)}); kept the sampling plan",
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


def _decomposed(scenario, initial_plan, options: RefineOptions, wrench_provider, progress) -> RefineResult:
    """Many vehicles: :func:`proxplan.planner.reoptimize.reoptimize_plan` (one vehicle at a time against the
    others' fixed trajectories, sparse pairs) within ``options.time_budget_s``."""
    from proxplan.planner.reoptimize import ReoptOptions, reoptimize_plan

    result = reoptimize_plan(
        scenario,
        initial_plan,
        wrench_provider=wrench_provider or default_wrench_provider,
        extent_provider=None if wrench_provider is not None else _table_extent,
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
