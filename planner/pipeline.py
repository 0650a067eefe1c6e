"""Multi-vehicle planning pipeline: prioritised space-time sampling, Ruckig timing, optional
refinement (``proxplan.planner.optimize.refine_plan``), metrics.

Vehicles are planned one after another (hovering vehicles first, then the others in file order with
every dock target before the vehicles docking to it). Each one is searched in space-time
(:mod:`proxplan.planner.sampling`) against the trajectories already planned (moving disturbance sources) and
the start positions of vehicles not planned yet (assumed to leave within ``LEAVE_START_S``). Its
path is timed with Ruckig (:mod:`proxplan.planner.timing`) and the timed trajectory is re-checked on the time
grid; a failed check retries with another seed. When a vehicle cannot be planned, planning restarts
once with that vehicle first; after that :class:`InfeasibleError` names the vehicle and constraint.

Docking: the search ends at an approach point on the dock axis, outside the source's invalid zone
(dz > 3 L, S0 II-A); the final straight approach to the dock at half speed crosses the invalid zone,
where the cutoff rule is suspended for the dock pair only (the two must meet there). The plan reports
the time spent in the invalid zone and ``proxplan verify`` checks the model's extrapolated authority
usage there.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np

from proxplan.planfile import Plan, Scenario, VehicleTrajectory
from proxplan.planner.constraints import Track, build_checker
from proxplan.planner.errors import InfeasibleError
from proxplan.planner.ordering import priority_order, promote
from proxplan.planner.precheck import (
    check_close_pairs,
    check_goal_tubes,
    check_starts_and_goals,
    check_swarm_size,
)
from proxplan.planner.sampling import GoalSpec, SamplingOptions, plan_space_time, start_conflict
from proxplan.planner.timing import (
    KinematicLimits,
    TimedPath,
    common_grid,
    min_segment_duration_s,
    time_parameterize,
    time_parameterize_through,
)
from proxplan.planner.validity import BatchChecker

METHODS = ("optimized", "sampling", "roadmap", "no-downwash", "ellipsoid")
MODE_OF_METHOD = {
    "optimized": "downwash",
    "roadmap": "downwash",
    "sampling": "downwash",
    "no-downwash": "no-downwash",
    "ellipsoid": "ellipsoid",
}
DT_S = 0.05  # common time grid of plan.json, s
LEAVE_START_S = 2.5  # vehicles not planned yet are assumed to have left their start by then, s
ATTEMPTS = 3  # seeds tried per vehicle before it counts as failed
DOCK_SPEED_FACTOR = 0.5  # final dock approach at this fraction of the vehicle's limits
PLAN_MARGIN_M = 0.02  # the search keeps this much more than the nominal limits, m (see build_checker)
PLAN_MARGIN_S = 0.2  # and assumes not-yet-planned vehicles leave their start this much later, s
MAX_REORDERS = 8  # conflict-driven re-orderings before a vehicle counts as infeasible


class _VehicleFailed(Exception):
    def __init__(self, vehicle: str, constraint: str, message: str, timed: dict[str, TimedPath]):
        super().__init__(message)
        self.vehicle, self.constraint, self.message = vehicle, constraint, message
        self.timed = timed  # the vehicles planned before the failure (reusable as a prefix)


def _plan_order(
    scenario: Scenario,
    order: list[str],
    *,
    mode: str,
    seed: int,
    options: SamplingOptions,
    progress,
    keep: dict[str, TimedPath] | None = None,
) -> tuple[dict[str, TimedPath], dict]:
    """Plan the vehicles in ``order``; ``keep`` holds already planned leading vehicles to reuse."""
    timed: dict[str, TimedPath] = {}
    tracks: dict[str, Track] = {}
    info: dict = {"attempts": {}, "rrt_vertices": {}}
    horizon = scenario.limits.time_horizon_s
    for idx, name in enumerate(order):
        task = scenario.vehicles[name]
        if keep and name in keep and len(timed) == idx:
            timed[name] = keep[name]
            tracks[name] = _track_of(name, task, keep[name])
            continue
        if progress:
            progress(f"planning {name}", idx / max(1, len(order)))
        others = [tracks[n] for n in timed]
        others += [
            Track.static(
                n,
                scenario.vehicles[n].vehicle,
                scenario.vehicles[n].start_m,
                until_s=math.inf if scenario.vehicles[n].hover else LEAVE_START_S,
            )
            for n in order
            if n not in timed and n != name
        ]
        checker = build_checker(scenario, name, others, mode=mode, margin_m=PLAN_MARGIN_M, until_margin_s=PLAN_MARGIN_S)
        nominal = build_checker(scenario, name, others, mode=mode)
        bad = start_conflict(nominal, task.start_m)
        if bad is not None:
            why = ""
            if bad == "workspace" or bad.startswith("obstacle"):
                why = (
                    f" (the body, radius {task.vehicle.body_radius_m:.3f} m, must keep clear horizontally and "
                    f"{scenario.limits.obstacle_margin_m:g} m vertically)"
                )
            raise InfeasibleError(
                name, bad, f"vehicle {name!r}: its start {task.start_m.tolist()} violates '{bad}' at t = 0{why}"
            )
        if task.hover:
            path = TimedPath(np.array([0.0]), task.start_m[None, :].copy(), [])
            timed[name] = path
            tracks[name] = Track.static(name, task.vehicle, task.start_m)
            continue
        limits = task.kinematic_limits
        hold_until = max([tr.end_s for tr in others if math.isfinite(tr.until_s) is False] + [LEAVE_START_S, 0.0]) + 1.0
        hold_until = max(hold_until, max([tr.end_s for tr in others] + [0.0]) + 1.0)
        if task.dock_with is not None:
            a, d = scenario.dock_geometry(name)
            slow = KinematicLimits(
                *(DOCK_SPEED_FACTOR * np.array([limits.max_speed_mps, limits.max_accel_mps2, limits.max_jerk_mps3]))
            )
            goal = GoalSpec(
                position_m=a, hold_until_s=hold_until, tail=[d], tail_exempt=task.dock_with, tail_limits=slow
            )
        else:
            assert task.goal_m is not None  # a moving vehicle that does not dock has a goal
            goal = GoalSpec(position_m=task.goal_m, hold_until_s=hold_until)
        accepted = None
        last_problem = None
        t_direct = min_segment_duration_s(float(np.linalg.norm(goal.position_m - task.start_m)), limits)
        t_busy = max([tr.end_s for tr in others] + [0.0])
        for attempt in range(ATTEMPTS):
            # search a short time window first (an RRT over a long one schedules slow paths)
            window = (max(2.0 * t_direct, t_direct + 6.0, t_busy + 2.0), max(4.0 * t_direct, t_busy + 15.0), horizon)[
                attempt
            ]
            sp = plan_space_time(
                checker,
                task.start_m,
                goal,
                limits,
                horizon_s=min(horizon, window),
                seed=seed * 1009 + idx * 31 + attempt,
                options=options,
            )
            if sp is None:
                last_problem = (
                    _goal_problem(nominal, goal) or checker.most_rejected() or "no path within the time budget"
                )
                continue
            if goal.tail and goal.tail_limits is not None:  # the dock approach is timed at the slower limits
                tp = _retime_with_tail(sp, limits, goal.tail_limits, len(goal.tail))
            else:
                tp = time_parameterize(sp.waypoints_m, sp.times_s, limits)
            if sp.info.get("direct") and not goal.tail:  # pass through the roadmap's corners if still valid
                smooth = time_parameterize_through(sp.waypoints_m, sp.times_s, limits)
                if smooth.duration_s < tp.duration_s and _recheck(nominal, smooth, goal, hold_until) is None:
                    tp = smooth
            problem = _recheck(nominal, tp, goal, hold_until)
            if problem is None:
                accepted = tp
                info["attempts"][name] = attempt + 1
                info["rrt_vertices"][name] = sp.info.get("rrt_vertices")
                break
            last_problem = problem
            info.setdefault("rejected", []).append(
                f"{name} attempt {attempt + 1}: timed trajectory violates '{problem}'"
            )
        if accepted is None:
            raise _VehicleFailed(
                name,
                last_problem or "unknown",
                f"vehicle {name!r}: no path found; most limiting constraint: '{last_problem}'",
                dict(timed),
            )
        timed[name] = accepted
        tracks[name] = _track_of(name, task, accepted)
    return timed, info


def _track_of(name: str, task, tp: TimedPath) -> Track:
    if not tp.segments:
        return Track.static(name, task.vehicle, tp.knot_p_m[0])
    p, _, _ = tp.sample(common_grid(tp.duration_s, DT_S))
    return Track.from_arrays(name, task.vehicle, DT_S, p)


def _goal_problem(checker, goal: GoalSpec) -> str | None:
    """The constraint that keeps the goal (or dock) occupied at the end of the horizon, if any."""
    end = goal.tail[-1] if goal.tail else goal.position_m
    for p, exclude in ((goal.position_m, None), (end, goal.tail_exempt)):
        c = checker.conflict(float(p[0]), float(p[1]), float(p[2]), goal.hold_until_s, exclude=exclude, resting=True)
        if c is not None:
            return f"{c} at the goal" if p is end else f"{c} at the dock approach point"
    return None


def _retime_with_tail(sp, limits: KinematicLimits, tail_limits: KinematicLimits, n_tail: int) -> TimedPath:
    main = time_parameterize(
        sp.waypoints_m[: len(sp.waypoints_m) - n_tail], sp.times_s[: len(sp.times_s) - n_tail], limits
    )
    tail = time_parameterize(sp.waypoints_m[len(sp.waypoints_m) - n_tail - 1 :], None, tail_limits)
    knots = np.concatenate([main.knot_t_s, main.knot_t_s[-1] + tail.knot_t_s[1:]])
    return TimedPath(knots, sp.waypoints_m.copy(), main.segments + tail.segments)


def _recheck(checker, tp: TimedPath, goal: GoalSpec, hold_until: float) -> str | None:
    """First conflict of the timed trajectory on a fine grid (dock target exempt on the tail); no
    tracking tube for a pair while both rest (speed < REST_SPEED_MPS), as in the verifier."""
    t_tail = tp.knot_t_s[-1 - len(goal.tail)] if goal.tail else math.inf
    t = np.arange(0.0, max(tp.duration_s, hold_until) + 1e-9, DT_S / 2)
    p, _, _ = tp.sample(t)
    batch = BatchChecker.from_checker(checker)
    head = t < t_tail - 1e-9
    _, c = batch.first_conflict(p[head], t[head])
    if c is None and not head.all():
        _, c = batch.first_conflict(p[~head], t[~head], exclude=goal.tail_exempt)
    return c


def plan_scenario(
    scenario: Scenario,
    *,
    method: str = "optimized",
    seed: int = 0,
    progress: Callable[[str, float], None] | None = None,
    options: SamplingOptions | None = None,
    time_budget_s: float | None = None,
) -> Plan:
    """Plan every vehicle of ``scenario``; raises :class:`InfeasibleError` when impossible.

    ``method``: "optimized" (sampling, then ``proxplan.planner.optimize.refine_plan`` when available),
    "roadmap" (shared lattice roadmap + priority-based search, :mod:`proxplan.planner.swarm_plan`;
    the sampling planner when the roadmap cannot express the scenario or its search fails, with a note),
    "sampling", "no-downwash" (separation only) or "ellipsoid" (keep-out ellipsoid baseline).
    ``progress(message, fraction)`` is called as vehicles are planned. ``time_budget_s``: wall-clock
    budget of the optimiser (default ``RefineOptions.time_budget_s``), s; it returns the best
    verified improvement found by then.
    """
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    if time_budget_s is not None and not time_budget_s > 0:
        from proxplan.fileio import UserError

        raise UserError(f"--time-budget: expected a positive number of seconds, got {time_budget_s:g}")
    from proxplan.verify import verify_plan

    options = options or SamplingOptions()
    t0 = time.perf_counter()
    mode = MODE_OF_METHOD[method]
    check_swarm_size(scenario)
    check_close_pairs(scenario)
    check_starts_and_goals(scenario, mode=mode)
    check_goal_tubes(scenario, mode=mode, margin_m=PLAN_MARGIN_M)
    plan, why_not = _roadmap_plan(scenario, progress=progress) if method == "roadmap" else (None, None)
    if plan is None:
        plan = _sampling_plan(scenario, mode=mode, seed=seed, options=options, progress=progress)
        if why_not:
            plan.notes.append(why_not)
            method = "sampling"
    if mode == "downwash" and plan.method != "roadmap":
        # safety net: the timed plan is re-checked per vehicle, but the verifier is independent
        bad = verify_plan(plan, scenario)
        if bad:
            retry = _sampling_plan(scenario, mode=mode, seed=seed + 7919, options=options, progress=progress)
            bad_retry = verify_plan(retry, scenario)
            note = f"the first sampling plan failed verification ({bad[0]}); re-planned"
            if len(bad_retry) < len(bad):
                plan = retry
            retry_note = note + ("" if not bad_retry else f"; still {len(bad_retry)} violation(s)")
            plan.notes.append(retry_note)
    plan.method = plan.method if plan.method == "roadmap" else (method if method != "optimized" else "sampling")
    if method == "optimized":
        plan = _refine(scenario, plan, seed=seed, progress=progress, time_budget_s=time_budget_s)
    finish_metrics(scenario, plan, planning_time_s=time.perf_counter() - t0)
    if progress:
        progress("done", 1.0)
    return plan


def _roadmap_plan(scenario: Scenario, *, progress) -> tuple[Plan | None, str | None]:
    """(the roadmap plan (:mod:`proxplan.planner.swarm_plan`), None) when the roadmap can express
    the scenario, the search succeeds and the verifier passes it; else (None, why not: a note for
    the sampling plan that replaces it)."""
    from proxplan.planner.swarm_plan import roadmap_applicable
    from proxplan.verify import verify_plan

    why = roadmap_applicable(scenario)
    if why is not None:
        return None, f"roadmap: not used, {why}; this is the sampling planner's plan"
    if progress:
        progress("roadmap search", 0.1)
    try:
        plan = plan_roadmap(scenario)
    except InfeasibleError as err:
        return None, f"roadmap: search failed ({err.message}); this is the sampling planner's plan"
    bad = verify_plan(plan, scenario)
    if bad:
        return None, f"roadmap: plan failed verification ({bad[0]}); this is the sampling planner's plan"
    return plan, None


def plan_roadmap(scenario: Scenario, options=None) -> Plan:
    """The roadmap plan of ``scenario`` (:func:`proxplan.planner.swarm_plan.roadmap_timed`,
    ``options`` a ``RoadmapOptions``) as a Plan with ``metrics["roadmap"]`` (metrics not final);
    InfeasibleError when the roadmap cannot express the scenario or its search fails."""
    from proxplan.planner.swarm_plan import roadmap_timed

    timed, info = roadmap_timed(scenario, options)
    plan = assemble_plan(scenario, timed, method="roadmap", notes=list(scenario.load_notes))
    plan.notes.append(info.pop("note"))
    plan.metrics["roadmap"] = info
    return plan


def _sampling_plan(scenario: Scenario, *, mode: str, seed: int, options: SamplingOptions, progress) -> Plan:
    """Prioritised sampling with conflict-driven re-ordering (:func:`proxplan.planner.ordering.promote`:
    a failed vehicle moves before the vehicle that blocked it; the vehicles in front keep their
    plans); the assembled plan (metrics not final)."""
    order = priority_order(scenario)
    notes: list[str] = list(scenario.load_notes)
    keep: dict[str, TimedPath] = {}
    seen = {tuple(order)}
    for restart in range(MAX_REORDERS + 1):
        try:
            timed, info = _plan_order(
                scenario, order, mode=mode, seed=seed, options=options, progress=progress, keep=keep
            )
            break
        except _VehicleFailed as fail:
            new, n_keep = promote(scenario, order, fail.vehicle, fail.constraint)
            if restart == MAX_REORDERS or tuple(new) in seen:
                raise InfeasibleError(fail.vehicle, fail.constraint, fail.message) from None
            seen.add(tuple(new))
            notes.append(
                f"re-ordering: {fail.vehicle} failed ({fail.constraint}); planned as number {new.index(fail.vehicle) + 1}"
            )
            keep = {n: fail.timed[n] for n in new[:n_keep] if n in fail.timed}
            order = new
    plan = assemble_plan(scenario, timed, method="sampling", notes=notes)
    plan.metrics["priority_order"] = order
    plan.metrics["sampling_attempts"] = info["attempts"]
    plan.metrics["seed"] = seed
    return plan


def _refine(scenario: Scenario, plan: Plan, *, seed: int, progress, time_budget_s: float | None = None) -> Plan:
    from proxplan.planner.optimize import RefineOptions, refine_plan

    options = RefineOptions() if time_budget_s is None else RefineOptions(time_budget_s=time_budget_s)
    try:
        result = refine_plan(scenario, plan, seed=seed, progress=progress, options=options)
    except Exception as err:  # noqa: BLE001 - the optimiser must never lose the sampling plan
        plan.notes.append(
            f"optimized: refinement raised {type(err).__name__}: {str(err).splitlines()[0] if str(err) else ''}; this is the sampling result"
        )
        plan.method = "sampling (optimizer failed)"
        return plan
    refined = result.plan
    if not result.success:
        plan.notes.append(f"optimized: refinement failed ({result.message}); this is the sampling result")
        plan.method = "sampling (optimizer fell back)"
        plan.solver = result.stats  # what IPOPT reported for the attempt that failed
        return plan
    refined.method = "optimized"
    refined.notes = list(dict.fromkeys(list(plan.notes) + list(refined.notes or [])))  # keep order, once each
    for key in ("priority_order", "sampling_attempts", "seed"):
        refined.metrics.setdefault(key, plan.metrics.get(key))
    refined.metrics["optimizer_solve_time_s"] = result.solve_time_s
    refined.metrics["optimizer_iterations"] = result.iterations
    refined.solver = result.stats
    refined.scenario_file = plan.scenario_file
    refined.scenario_spec = plan.scenario_spec
    return refined


def assemble_plan(scenario: Scenario, timed: dict[str, TimedPath], *, method: str, notes: list[str]) -> Plan:
    """Sample every timed path on one common grid (file order of vehicles) into a Plan."""
    end = max([tp.duration_s for tp in timed.values()] + [DT_S])
    grid = common_grid(end, DT_S)
    vehicles = {}
    for name, task in scenario.vehicles.items():
        p, v, a = timed[name].sample(grid)
        vehicles[name] = VehicleTrajectory(name, task.type_name, task.vehicle, grid.copy(), p, v, a)
    notes = list(notes)
    for name, task in scenario.vehicles.items():
        if task.dock_with is not None:
            a_pt, d_pt = scenario.dock_geometry(name)
            notes.append(
                f"dock {name} -> {task.dock_with}: final approach from {np.round(a_pt, 3).tolist()} to "
                f"{np.round(d_pt, 3).tolist()} at {DOCK_SPEED_FACTOR:g} x speed crosses the model's invalid zone "
                f"(dz <= 3 L, S0 II-A); the cutoff rule is suspended for this pair there and verify checks the "
                f"model's extrapolated usage"
            )
    return Plan(
        scenario=scenario.name,
        dt_s=DT_S,
        vehicles=vehicles,
        metrics={},
        method=method,
        notes=notes,
        scenario_file=scenario.source_path,
        scenario_spec=scenario.to_spec(),
    )


def finish_metrics(scenario: Scenario, plan: Plan, *, planning_time_s: float) -> None:
    """Fill the DESIGN metrics (planning_time_s, max_authority_usage, min_separation_m, makespan_s)
    and extras (per-vehicle usage, path length, arrival time, invalid-zone time of docks)."""
    from proxplan.verify import attach_feedforward, separation_summary, wrench_along_plan

    t = plan.t_s
    along = wrench_along_plan(plan, scenario, t_s=t)
    attach_feedforward(plan, along)  # the predicted wrench, for controllers that feed it forward
    usage = {n: max(0.0, float(a.usage.max())) for n, a in along.items()}
    sep = separation_summary(plan, scenario)
    moving_end = 0.0
    for tr in plan.vehicles.values():
        moving = np.linalg.norm(tr.velocity_mps, axis=1) > 1e-4
        if moving.any():
            moving_end = max(
                moving_end,
                float(tr.t_s[np.nonzero(moving)[0][-1] + 1 if np.nonzero(moving)[0][-1] + 1 < tr.t_s.size else -1]),
            )
    plan.metrics.update(
        {
            "planning_time_s": round(float(planning_time_s), 4),
            "max_authority_usage": max(usage.values()) if usage else 0.0,
            "min_separation_m": sep["min_separation_m"],
            "makespan_s": float(moving_end),
            "authority_fraction": scenario.limits.authority_fraction,
            "tracking_margin_m": scenario.limits.tracking_margin_m,
            "authority_usage_by_vehicle": usage,
            "invalid_zone_s_by_vehicle": {n: float(a.invalid_zone.sum() * plan.dt_s) for n, a in along.items()},
            "min_dock_separation_m": sep["min_dock_separation_m"],
            "path_length_m": {
                n: float(np.linalg.norm(np.diff(tr.position_m, axis=0), axis=1).sum())
                for n, tr in plan.vehicles.items()
            },
        }
    )
