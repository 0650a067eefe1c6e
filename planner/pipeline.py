"""Multi-vehicle planning pipeline: pre-checks, the chosen planner (prioritised space-time sampling,
:mod:`proxplan.planner.sampling`, or the swarm layer, :mod:`proxplan.planner.swarm`), the
independent verifier as a safety net, optional refinement (:func:`proxplan.planner.optimizer.refine_plan`)
and the plan's metrics.

Docking: the final straight approach to the dock crosses the invalid zone, where the cutoff rule is
suspended for the dock pair only (the two must meet there). The plan reports the time spent in the
invalid zone and ``proxplan verify`` checks the model's extrapolated authority usage there.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from proxplan.planfile import Plan, Scenario
from proxplan.planner.checks.precheck import (
    check_goal_loops,
    check_goal_tubes,
    check_starts_and_goals,
    check_swarm_size,
)
from proxplan.planner.errors import PlanNotFound
from proxplan.planner.sampling.prioritized import PLAN_MARGIN_M, sampling_plan
from proxplan.planner.sampling.spec import SamplingOptions
from proxplan.planner.timing.plan_grid import DT_S, assemble_plan

__all__ = ["DT_S", "METHODS", "PLAN_MARGIN_M", "deflection_allowance", "finish_metrics", "plan_scenario"]

METHODS = ("optimized", "sampling", "roadmap", "no-downwash", "ellipsoid")
MODE_OF_METHOD = {
    "optimized": "downwash",
    "roadmap": "downwash",
    "sampling": "downwash",
    "no-downwash": "no-downwash",
    "ellipsoid": "ellipsoid",
}


def plan_scenario(
    scenario: Scenario,
    *,
    method: str = "optimized",
    seed: int = 0,
    progress: Callable[[str, float], None] | None = None,
    options: SamplingOptions | None = None,
    time_budget_s: float | None = None,
    max_time_s: float | None = None,
) -> Plan:
    """Plan every vehicle of ``scenario``; raises :class:`InfeasibleError` when impossible.

    ``method``: "optimized" (sampling, then ``proxplan.planner.optimizer.refine_plan`` when available),
    "roadmap" (the swarm layer, :mod:`proxplan.planner.swarm.plan`; the sampling planner when it
    cannot plan the scenario or its search gives up, with a note),
    "sampling", "no-downwash" (separation only) or "ellipsoid" (keep-out ellipsoid baseline).
    ``progress(message, fraction)`` is called as vehicles are planned. ``time_budget_s``: wall-clock
    budget of the optimiser (default ``RefineOptions.time_budget_s``), s; it returns the best
    verified improvement found by then. ``max_time_s``: wall-clock budget of the whole plan, s;
    a search still running then stops with :class:`PlanNotFound` ("not found within ..."), never
    with a different plan.

    Swarms (``method="roadmap"``, and ``"optimized"`` for scenarios of
    ``proxplan.planner.swarm.SWARM_MIN_VEHICLES`` vehicles or more without docks) go through
    :mod:`proxplan.planner.swarm`; ``assign_goals: by_type`` is applied first
    (:func:`proxplan.planner.swarm.goals.apply_assignment`) and recorded in ``plan.metrics``.
    """
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    if time_budget_s is not None and not time_budget_s > 0:
        from proxplan.fileio import UserError

        raise UserError(f"--time-budget: expected a positive number of seconds, got {time_budget_s:g}")
    from proxplan.planner.swarm.goals import apply_assignment
    from proxplan.verify import verify_plan

    options = options or SamplingOptions()
    t0 = time.perf_counter()
    deadline = None if max_time_s is None else t0 + float(max_time_s)
    mode = MODE_OF_METHOD[method]
    check_swarm_size(scenario)
    scenario, assignment = apply_assignment(scenario)
    check_starts_and_goals(scenario, mode=mode)
    check_goal_tubes(scenario, mode=mode, margin_m=PLAN_MARGIN_M)
    if mode == "downwash":
        check_goal_loops(scenario)
    swarm = method == "roadmap" or (method == "optimized" and _is_swarm(scenario))
    plan, why_not = (
        _swarm_plan(scenario, seed=seed, progress=progress, deadline=deadline, optimize=method == "optimized")
        if swarm
        else (None, None)
    )
    if (
        plan is not None
        and plan.metrics["swarm"]["stage"] == "lattice"
        and len(scenario.vehicles) <= SAMPLING_ALTERNATIVE_MAX_VEHICLES
    ):
        plan = _shorter_with_sampling(
            scenario, plan, mode=mode, seed=seed, options=options, progress=progress, deadline=deadline
        )
    from_swarm = plan is not None
    if plan is None:
        if deadline is not None and time.perf_counter() > deadline:
            raise PlanNotFound(f"no plan found within the time budget of {max_time_s:g} s ({why_not})")
        plan = sampling_plan(scenario, mode=mode, seed=seed, options=options, progress=progress)
        if why_not:
            plan.notes.append(why_not)
            method = "sampling"
    bad = []
    if mode == "downwash" and not from_swarm:
        # safety net: the timed plan is re-checked per vehicle, but the verifier is independent
        bad = verify_plan(plan, scenario)
        if bad and not options.deflection_m:
            plan, bad = _with_deflections(scenario, plan, bad, mode=mode, seed=seed, options=options, progress=progress)
        if bad:
            retry = sampling_plan(scenario, mode=mode, seed=seed + 7919, options=options, progress=progress)
            bad_retry = verify_plan(retry, scenario)
            note = f"the first sampling plan failed verification ({bad[0]}); re-planned"
            if len(bad_retry) < len(bad):
                plan = retry
            retry_note = note + ("" if not bad_retry else f"; still {len(bad_retry)} violation(s)")
            plan.notes.append(retry_note)
            bad = bad_retry if plan is retry else bad
    if not from_swarm:
        plan.method = method if method != "optimized" else "sampling"
    if method == "optimized" and not swarm:
        plan = _refine(scenario, plan, seed=seed, progress=progress, time_budget_s=time_budget_s)
    elif mode == "downwash" and not bad:
        plan.metrics["verified"] = True  # the verifier passed this very plan (the CLI need not re-run it)
    if assignment is not None:
        plan.metrics["assignment"] = assignment
        plan.metrics["assignment_lower_bound_s"] = assignment["lower_bound_s"]
    finish_metrics(scenario, plan, planning_time_s=time.perf_counter() - t0)
    if progress:
        progress("done", 1.0)
    return plan


def deflection_allowance(plan: Plan, scenario: Scenario) -> dict[str, float]:
    """Per vehicle the largest distance, m, its controller is predicted to be pushed off the plan by
    the plan's own predicted disturbance (``proxplan.verify.deflection_along_plan``), for vehicles
    pushed at all: the tube growth the planner's second pass keeps others clear of."""
    from proxplan.verify import deflection_along_plan, wrench_along_plan

    t = np.arange(0.0, float(plan.t_s[-1]) + 0.005, 0.01)
    along = wrench_along_plan(plan, scenario, t_s=t)
    return {n: float(d.max()) for n, d in deflection_along_plan(plan, scenario, along).items() if d.max() > 0.0}


def _with_deflections(
    scenario: Scenario, plan: Plan, bad: list, *, mode: str, seed: int, options: SamplingOptions, progress
) -> tuple[Plan, list]:
    """A plan that fails the verifier is planned again with each disturbed vehicle's tube grown by
    its largest predicted deflection in the first plan (:func:`deflection_allowance`): the
    verifier grows the tube by the deflection where it applies, the planner's checker by its
    largest value throughout. The plan with fewer violations is kept, with a note."""
    from dataclasses import replace

    from proxplan.verify import verify_plan

    extra = deflection_allowance(plan, scenario)
    if not extra:
        return plan, bad
    again = sampling_plan(
        scenario, mode=mode, seed=seed, options=replace(options, deflection_m=extra), progress=progress
    )
    bad_again = verify_plan(again, scenario)
    grown = ", ".join(f"{n} {100 * d:.1f} cm" for n, d in sorted(extra.items()))
    if len(bad_again) < len(bad):
        again.notes.append(
            f"planned again with the tubes of disturbed vehicles grown by their predicted deflection ({grown}): "
            f"the first plan failed verification ({bad[0]})"
        )
        return again, bad_again
    plan.notes.append(f"planning again with tubes grown by the predicted deflections ({grown}) did not help")
    return plan, bad


def _shorter_with_sampling(
    scenario: Scenario, plan: Plan, *, mode: str, seed: int, options: SamplingOptions, progress, deadline
) -> Plan:
    """The swarm layer's lattice plan flown in lock-step (its guaranteed answer, when prioritised
    planning gave up) or, when it is shorter and passes the verifier, the sampling planner's plan
    (one vehicle at a time in continuous space-time): the two fail on different layouts. It has no
    deadline of its own: it starts only before the caller's deadline, and only up to
    ``SAMPLING_ALTERNATIVE_MAX_VEHICLES`` vehicles."""
    from proxplan.planner.errors import InfeasibleError
    from proxplan.planner.optimizer.acceptance import moving_end_s
    from proxplan.verify import verify_plan

    if deadline is not None and time.perf_counter() > deadline:
        return plan
    try:
        other = sampling_plan(scenario, mode=mode, seed=seed, options=options, progress=progress)
    except (InfeasibleError, PlanNotFound) as err:
        plan.notes.append(f"the sampling planner was tried as well and found no plan ({err})")
        return plan
    mine, theirs = moving_end_s(plan), moving_end_s(other)
    if theirs >= mine or verify_plan(other, scenario):
        plan.notes.append(f"the sampling planner was tried as well: {theirs:.2f} s, not shorter or not verified")
        return plan
    other.method = plan.method
    other.metrics.update({k: v for k, v in plan.metrics.items() if k in ("swarm", "lower_bound_s", "seed")})
    other.metrics["verify_violations"] = 0
    other.notes.append(
        f"sampling planner's plan ({theirs:.2f} s): shorter than the swarm layer's lattice plan in lock-step ({mine:.2f} s)"
    )
    return other


def _is_swarm(scenario: Scenario) -> bool:
    """A formation change for the swarm layer: enough vehicles and no docks."""
    from proxplan.planner.swarm import SWARM_MIN_VEHICLES, swarm_applicable

    return len(scenario.vehicles) >= SWARM_MIN_VEHICLES and swarm_applicable(scenario) is None


def _swarm_plan(scenario: Scenario, *, seed: int, progress, deadline, optimize: bool) -> tuple[Plan | None, str | None]:
    """(the swarm layer's plan (:func:`proxplan.planner.swarm.swarm_timed`), None) when it can plan
    the scenario and the verifier passes the plan; else (None, why not: a note for the sampling
    plan that replaces it)."""
    from dataclasses import replace

    from proxplan.planner.swarm import SearchGaveUp, SwarmOptions, swarm_applicable

    why = swarm_applicable(scenario)
    if why is not None:
        return None, f"swarm layer: not used, {why}; this is the sampling planner's plan"
    options = SwarmOptions(seed=seed, passes=SwarmOptions.passes + (OPTIMIZE_EXTRA_PASSES if optimize else 0))
    method = "optimized" if optimize else "roadmap"
    try:
        plan, bad = _swarm_attempt(scenario, options, method, seed=seed, progress=progress, deadline=deadline)
        if bad:
            # the verifier grows a disturbed vehicle's tube by its predicted deflection; plan again
            # with every keep-out grown by twice the largest one of the first plan (a pair's growth
            # is the sum of its two vehicles' deflections)
            extra = deflection_allowance(plan, scenario)
            if extra:
                grow_m = 2.0 * max(extra.values())
                again, bad_again = _swarm_attempt(
                    scenario,
                    replace(options, deflection_m=grow_m),
                    method,
                    seed=seed,
                    progress=progress,
                    deadline=deadline,
                )
                if not bad_again:
                    again.notes.append(
                        f"swarm layer: keep-outs grown by {100 * grow_m:.1f} cm for the predicted deflections "
                        f"(the first plan failed verification: {bad[0]})"
                    )
                    plan, bad = again, bad_again
    except SearchGaveUp as err:
        return None, f"swarm layer: {err.message}; this is the sampling planner's plan"
    if bad:
        return None, f"swarm layer: plan failed verification ({bad[0]}); this is the sampling planner's plan"
    plan.metrics["verify_violations"] = 0
    return plan, None


OPTIMIZE_EXTRA_PASSES = 5  # continuous re-timing passes that ``optimized`` adds for swarms
# the sampling planner is tried beside a lattice plan in lock-step up to this many vehicles (measured
# at 32 / 64: 2.0-2.2x the lower bound in 5-85 s where it finishes; beyond, its time is unbounded)
SAMPLING_ALTERNATIVE_MAX_VEHICLES = 64


def _swarm_attempt(scenario: Scenario, options, method: str, *, seed: int, progress, deadline) -> tuple[Plan, list]:
    """The swarm layer's plan with ``options`` and what the verifier says of it (SearchGaveUp passes)."""
    from proxplan.planner.swarm import swarm_timed
    from proxplan.verify import verify_plan

    timed, info = swarm_timed(scenario, options, progress=progress, deadline=deadline)
    plan = assemble_plan(scenario, timed, method=method, notes=list(scenario.load_notes))
    plan.notes.append(f"swarm layer: {info['coordination']}")
    plan.metrics["swarm"] = info
    plan.metrics["lower_bound_s"] = info["lower_bound_s"]
    plan.metrics["seed"] = seed
    return plan, verify_plan(plan, scenario)


def _refine(scenario: Scenario, plan: Plan, *, seed: int, progress, time_budget_s: float | None = None) -> Plan:
    from proxplan.planner.optimizer import RefineOptions, refine_plan

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
