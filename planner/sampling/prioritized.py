"""Prioritised planning with the space-time sampler: one vehicle after another, with conflict-driven
re-ordering.

Vehicles are planned one after another (:func:`proxplan.planner.sampling.ordering.priority_order`:
hovering vehicles first, then the others by decreasing unobstructed flight time, every dock target
before the vehicles docking to it). Each one is searched in space-time
(:mod:`proxplan.planner.sampling.space_time`) against the trajectories already planned (moving
disturbance sources) and the start positions of vehicles not planned yet (assumed to leave within
``LEAVE_START_S``). Its path is timed with Ruckig (:mod:`proxplan.planner.timing`) and the timed
trajectory is re-checked on the time grid; a failed check retries with another seed. When a vehicle
cannot be planned, :func:`proxplan.planner.sampling.ordering.promote` moves it before the vehicle
that blocked it and planning restarts (the vehicles in front keep their plans); after
``MAX_REORDERS`` re-orderings (or an order already tried) it gives up: :class:`PlanNotFound` names the
vehicle and constraint. A sampling search that gave up proves nothing, so it is never "infeasible".

The search keeps ``PLAN_MARGIN_M`` more than the nominal keep-outs (a search device: its timed
trajectory is re-checked with the nominal rules, which sample the motion differently), except against
the vehicles of :func:`margin_free` (issue 37, round 37Z): where the margin alone would keep the pair
apart at the vehicle's goal (the other resting at its final position) or at its start, the margin
would forbid an arrival or a departure the verifier passes, so that pair is searched with the
nominal rule, the verifier's (``proxplan.planner.checks.precheck.rest_pair_conflicts``, the rule the
pipeline's pre-check applies before any search). Every timed trajectory is re-checked with the
nominal rules and every plan verified, as before.

Docking: the search ends at an approach point on the dock axis, outside the source's invalid zone
(dz > 3 L, S0 II-A); the final straight approach to the dock at ``DOCK_SPEED_FACTOR`` of the limits
crosses the invalid zone, where the cutoff rule is suspended for the dock pair only (the two must
meet there).
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from proxplan.physics import KinematicLimits
from proxplan.planfile import Plan, Scenario
from proxplan.planner.checks.constraints import Track, build_checker
from proxplan.planner.checks.precheck import rest_pair_conflicts
from proxplan.planner.checks.validity import BatchChecker
from proxplan.planner.errors import InfeasibleError, PlanNotFound
from proxplan.planner.sampling.ordering import priority_order, promote
from proxplan.planner.sampling.space_time import plan_space_time, start_conflict
from proxplan.planner.sampling.spec import GoalSpec, SamplingOptions
from proxplan.planner.timing.durations import min_segment_duration_s
from proxplan.planner.timing.paths import TimedPath, common_grid, time_parameterize, time_parameterize_through
from proxplan.planner.timing.plan_grid import DOCK_SPEED_FACTOR, DT_S, MOVING_SPEED_MPS, assemble_plan

LEAVE_START_S = 2.5  # vehicles not planned yet are assumed to have left their start by then, s
ATTEMPTS = 3  # seeds tried per vehicle before it counts as failed
PLAN_MARGIN_M = 0.02  # the search keeps this much more than the nominal limits, m (see build_checker)
PLAN_MARGIN_S = 0.2  # and assumes not-yet-planned vehicles leave their start this much later, s
MAX_REORDERS = 8  # conflict-driven re-orderings before the sampling planner gives up (PlanNotFound), -


class _VehicleFailed(Exception):
    def __init__(self, vehicle: str, constraint: str, message: str, timed: dict[str, TimedPath]):
        super().__init__(message)
        self.vehicle, self.constraint, self.message = vehicle, constraint, message
        self.timed = timed  # the vehicles planned before the failure (reusable as a prefix)


def plan_order(
    scenario: Scenario,
    order: list[str],
    *,
    mode: str,
    seed: int,
    options: SamplingOptions,
    progress,
    keep: dict[str, TimedPath] | None = None,
    searches: list[int] | None = None,
) -> tuple[dict[str, TimedPath], dict]:
    """Plan the vehicles in ``order``; ``keep`` holds already planned leading vehicles to reuse.
    ``searches``: a one-element counter of single-vehicle searches, checked against
    ``options.max_searches`` (:class:`PlanNotFound` when spent)."""
    searches = [0] if searches is None else searches
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
        extra = options.deflection_m
        checker = build_checker(
            scenario,
            name,
            others,
            mode=mode,
            margin_m=PLAN_MARGIN_M,
            until_margin_s=PLAN_MARGIN_S,
            extra_tube_m=extra,
            no_margin=margin_free(scenario, name, mode=mode, extra_tube_m=extra),
        )
        nominal = build_checker(scenario, name, others, mode=mode, extra_tube_m=extra)
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
            searches[0] += 1
            if options.max_searches is not None and searches[0] > options.max_searches:
                raise PlanNotFound(
                    f"the sampling planner's budget of {options.max_searches} single-vehicle searches is spent",
                    vehicles=[name],
                )
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
        if options.beat_s is not None and _arrival_s(accepted) >= options.beat_s:
            raise PlanNotFound(
                f"the sampling planner stopped: {name} arrives at {_arrival_s(accepted):.2f} s, not before "
                f"{options.beat_s:.2f} s, so its plan could not be shorter",
                vehicles=[name],
            )
        timed[name] = accepted
        tracks[name] = _track_of(name, task, accepted)
    return timed, info


def margin_free(
    scenario: Scenario, name: str, *, mode: str, extra_tube_m: Mapping[str, float] | None = None
) -> frozenset[str]:
    """The other vehicles that ``name`` is searched against without ``PLAN_MARGIN_M`` (module
    docstring): those whose keep-out while either moves (the verifier's rule,
    :func:`~proxplan.planner.checks.precheck.rest_pair_conflicts`, with the predicted deflections
    ``extra_tube_m``, m) grown by the margin holds ``name``'s goal where they end, or ``name``'s start
    where they start. Empty where no goal or start lies within a margin of another vehicle's."""
    task = scenario.vehicles[name]
    if task.hover:
        return frozenset()
    others = [o for o in scenario.vehicles if o != name]

    def held_by(point_m: np.ndarray, rests_m: Mapping[str, np.ndarray]) -> set[str]:
        return set(
            rest_pair_conflicts(
                scenario, name, point_m, rests_m, mode=mode, margin_m=PLAN_MARGIN_M, extra_tube_m=extra_tube_m
            )
        )

    out = held_by(task.start_m, {o: scenario.vehicles[o].start_m for o in others})
    if task.dock_with is None and task.goal_m is not None:
        final = {o: scenario.final_position_m(o) for o in others if scenario.vehicles[o].dock_with != name}
        out |= held_by(task.goal_m, final)
    return frozenset(out)


def _arrival_s(tp: TimedPath) -> float:
    """When ``tp`` stops moving on the plan's grid, s: its ``vehicle_arrival_s`` in the assembled plan
    (the same grid from 0 and the same speed threshold), so a plan holding it has a makespan >= this."""
    if not tp.segments:
        return 0.0
    grid = common_grid(tp.duration_s, DT_S)
    _, v, _ = tp.sample(grid)
    moving = np.flatnonzero(np.linalg.norm(v, axis=1) > MOVING_SPEED_MPS)
    return float(grid[min(int(moving[-1]) + 1, grid.size - 1)]) if moving.size else 0.0


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


def sampling_plan(scenario: Scenario, *, mode: str, seed: int, options: SamplingOptions, progress) -> Plan:
    """Prioritised sampling with conflict-driven re-ordering (:func:`proxplan.planner.sampling.ordering.promote`:
    a failed vehicle moves before the vehicle that blocked it; the vehicles in front keep their
    plans); the assembled plan (metrics not final)."""
    order = priority_order(scenario)
    notes: list[str] = list(scenario.load_notes)
    keep: dict[str, TimedPath] = {}
    seen = {tuple(order)}
    searches = [0]
    for restart in range(MAX_REORDERS + 1):
        try:
            timed, info = plan_order(
                scenario, order, mode=mode, seed=seed, options=options, progress=progress, keep=keep, searches=searches
            )
            break
        except _VehicleFailed as fail:
            new, n_keep = promote(scenario, order, fail.vehicle, fail.constraint)
            if restart == MAX_REORDERS or tuple(new) in seen:  # a search's verdict, not a proof: it gave up
                raise PlanNotFound(
                    f"the sampling planner gave up after {restart} re-ordering(s): {fail.message}",
                    vehicles=[fail.vehicle],
                    details={"constraint": fail.constraint, "reorderings": restart},
                ) from None
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
