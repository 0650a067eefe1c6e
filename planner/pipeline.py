"""Multi-vehicle planning pipeline: pre-checks, the chosen planner (prioritised space-time sampling,
:mod:`proxplan.planner.sampling`, or the swarm roadmap, :mod:`proxplan.planner.swarm`), the
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
    check_goal_tubes,
    check_starts_and_goals,
    check_swarm_size,
)
from proxplan.planner.errors import InfeasibleError
from proxplan.planner.sampling.prioritized import PLAN_MARGIN_M, sampling_plan
from proxplan.planner.sampling.spec import SamplingOptions
from proxplan.planner.timing.plan_grid import DT_S, assemble_plan

__all__ = ["DT_S", "METHODS", "PLAN_MARGIN_M", "finish_metrics", "plan_roadmap", "plan_scenario"]

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
) -> Plan:
    """Plan every vehicle of ``scenario``; raises :class:`InfeasibleError` when impossible.

    ``method``: "optimized" (sampling, then ``proxplan.planner.optimizer.refine_plan`` when available),
    "roadmap" (shared lattice roadmap + priority-based search, :mod:`proxplan.planner.swarm.plan`;
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
    check_starts_and_goals(scenario, mode=mode)
    check_goal_tubes(scenario, mode=mode, margin_m=PLAN_MARGIN_M)
    plan, why_not = _roadmap_plan(scenario, progress=progress) if method == "roadmap" else (None, None)
    if plan is None:
        plan = sampling_plan(scenario, mode=mode, seed=seed, options=options, progress=progress)
        if why_not:
            plan.notes.append(why_not)
            method = "sampling"
    if mode == "downwash" and plan.method != "roadmap":
        # safety net: the timed plan is re-checked per vehicle, but the verifier is independent
        bad = verify_plan(plan, scenario)
        if bad:
            retry = sampling_plan(scenario, mode=mode, seed=seed + 7919, options=options, progress=progress)
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
    """(the roadmap plan (:mod:`proxplan.planner.swarm.plan`), None) when the roadmap can express
    the scenario, the search succeeds and the verifier passes it; else (None, why not: a note for
    the sampling plan that replaces it)."""
    from proxplan.planner.swarm.plan import roadmap_applicable
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
    """The roadmap plan of ``scenario`` (:func:`proxplan.planner.swarm.plan.roadmap_timed`,
    ``options`` a ``RoadmapOptions``) as a Plan with ``metrics["roadmap"]`` (metrics not final);
    InfeasibleError when the roadmap cannot express the scenario or its search fails."""
    from proxplan.planner.swarm.plan import roadmap_timed

    timed, info = roadmap_timed(scenario, options)
    plan = assemble_plan(scenario, timed, method="roadmap", notes=list(scenario.load_notes))
    plan.notes.append(info.pop("note"))
    plan.metrics["roadmap"] = info
    return plan


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
