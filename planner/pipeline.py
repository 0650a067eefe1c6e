"""The planning pipeline, top to bottom: one named stage after another, each with typed inputs and
outputs (:func:`plan_scenario`).

1. *Prepare* (:func:`_prepare`): goals of interchangeable vehicles (``assign_goals: by_type``,
   :func:`proxplan.planner.swarm.goals.apply_assignment`), then the checks before any search (user
   mistakes, proven infeasibility).
2. *Swarm layer* (:func:`_swarm_stage`; formation changes, :mod:`proxplan.planner.swarm`): its plan
   once the verifier passes it, or why there is none (:class:`SwarmOutcome`).
3. *Sampling planner* (:func:`_sampling_stage`, :mod:`proxplan.planner.sampling`): the plan where
   the swarm layer is not used or gave up (then within a count budget, :func:`_counted`: it says
   "not found" once spent); beside the swarm layer's prioritised or lattice plan it runs as well,
   within the same budget, and the shorter verified plan is kept.
4. *Refine* (:func:`proxplan.planner.refine_stage.refine_stage`): ``optimized`` refines with CasADi
   (:func:`proxplan.planner.optimizer.refine_plan`; joint moves for swarms).
5. *Record* (:func:`_record`): the typed records of the stages into ``plan.metrics``, and the DESIGN
   metrics (:func:`proxplan.planner.metrics.finish_metrics`).

Every planner's plan goes through one verification policy (:func:`_until_verified`): the verifier
runs on it; a plan it rejects is planned again once with every disturbed vehicle's tube grown by its
predicted deflection (:func:`proxplan.planner.metrics.deflection_allowance`; a pair's keep-out grows
by the sum of its two vehicles' values, as in the verifier), then once more with another seed; the
plan with the fewest violations is kept, with a note. The swarm layer's prioritised planning, where
it gave up, is not run again in these re-plans (:func:`_no_narrower`).

Docking: the final straight approach to the dock crosses the invalid zone, where the cutoff rule is
suspended for the dock pair only (the two must meet there). The plan reports the time spent in the
invalid zone and ``proxplan verify`` checks the model's extrapolated authority usage there.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import asdict, dataclass, replace
from typing import Literal

from proxplan.planfile import Plan, Scenario
from proxplan.planner.bounds import certified_bound
from proxplan.planner.checks.precheck import (
    check_goal_loops,
    check_goal_tubes,
    check_starts_and_goals,
    check_swarm_size,
)
from proxplan.planner.errors import InfeasibleError, PlanNotFound
from proxplan.planner.metrics import DEFLECTION_DT_S, deflection_allowance, finish_metrics
from proxplan.planner.refine_stage import refine_stage
from proxplan.planner.sampling.prioritized import PLAN_MARGIN_M, sampling_plan
from proxplan.planner.sampling.spec import SamplingOptions
from proxplan.planner.swarm import SWARM_MIN_VEHICLES, SwarmInfo, SwarmOptions, swarm_applicable, swarm_timed
from proxplan.planner.swarm.goals import apply_assignment
from proxplan.planner.timing.plan_grid import DT_S, assemble_plan, moving_end_s

Method = Literal["optimized", "sampling", "swarm", "no-downwash", "ellipsoid"]
METHODS: tuple[Method, ...] = ("optimized", "sampling", "swarm", "no-downwash", "ellipsoid")
# the constraint set each method plans with (the two baselines plan without the downwash cut-offs)
MODE_OF_METHOD: dict[Method, str] = {
    "optimized": "downwash",
    "swarm": "downwash",
    "sampling": "downwash",
    "no-downwash": "no-downwash",
    "ellipsoid": "ellipsoid",
}
OPTIMIZE_EXTRA_PASSES = 5  # continuous re-timing passes that ``optimized`` adds for swarms
# the sampling planner runs beside the swarm layer's prioritised or lattice plan up to this many
# vehicles, with a count budget (below), and stops at its first vehicle arriving no earlier than the
# swarm plan (``SamplingOptions.beat_s``). Set watching the named layouts at 64 fixed (docs/planner.md,
# issue 37 round 9A), not the randomised family: beside a prioritised plan its budget took more than
# 60 s of CPU (circle, 3-4 s per vehicle) against 31 s for the swarm layer's whole attempt, and at 64
# by_type it was never the shorter plan (grid, circle, corridor); beside the lattice plan it never
# replaced grid-64's (6.94x kept in every run since round 6) and on corridor-64 spent its 128 searches (about 140 s of CPU, more than the swarm layer's
# whole attempt) without a plan, the lattice plan's 9.7x never beaten by any vehicle it planned
SAMPLING_ALTERNATIVE_MAX_VEHICLES = 32
# the sampling planner's count budget beside the swarm layer and after it gave up (_counted):
# single-vehicle searches per vehicle (re-orderings included): one pass through the order needs one
# per vehicle, the second leaves each vehicle one more seed or re-ordering on average
ALTERNATIVE_SEARCHES_PER_VEHICLE = 2
ALTERNATIVE_RRT_ITERATIONS = 10000  # RRT iterations per solve (the waiting search finds most paths)
RETRY_SEED_OFFSET = 7919  # the verification policy's last attempt plans with seed + this (a prime)

__all__ = ["DT_S", "METHODS", "PLAN_MARGIN_M", "Method", "SwarmOutcome", "deflection_allowance", "plan_scenario"]


@dataclass(frozen=True)
class _Run:
    """What every stage needs to know about the request (options passed in, never patched)."""

    method: Method
    mode: str  # constraint set (MODE_OF_METHOD)
    seed: int
    sampling: SamplingOptions
    swarm: SwarmOptions
    time_budget_s: float | None  # the optimiser's wall-clock budget, s
    t0: float  # time.perf_counter() at the start, s
    deadline: float | None  # time.perf_counter() value of --max-time, s
    progress: Callable[..., None] | None  # (message[, fraction]): the planners call it with one or two
    alternative: bool = True  # the sampling planner beside the swarm layer

    def past_deadline(self) -> bool:
        return self.deadline is not None and time.perf_counter() > self.deadline


@dataclass
class SwarmOutcome:
    """Stage 2: the swarm layer's verified plan and its info, or (None, why not) for a note."""

    plan: Plan | None
    info: SwarmInfo | None
    why_not: str | None
    searched: bool = True  # the swarm layer ran (False: it cannot plan this scenario, not used)


def plan_scenario(
    scenario: Scenario,
    *,
    method: str = "optimized",
    seed: int = 0,
    progress: Callable[[str, float], None] | None = None,
    options: SamplingOptions | None = None,
    swarm_options: SwarmOptions | None = None,
    time_budget_s: float | None = None,
    max_time_s: float | None = None,
    sampling_alternative: bool = True,
) -> Plan:
    """Plan every vehicle of ``scenario`` through the stages of the module; raises
    :class:`InfeasibleError` when proven impossible, :class:`PlanNotFound` when a search gave up.

    ``method``: one of :data:`METHODS`: "optimized" (sampling, then CasADi refinement; formation
    changes of ``SWARM_MIN_VEHICLES`` or more without docks go through the swarm layer), "swarm"
    (the swarm layer; the sampling planner when it cannot plan the scenario or its search gives up,
    with a note), "sampling", "no-downwash" (separation only) or "ellipsoid" (keep-out ellipsoid
    baseline). ``options`` / ``swarm_options``: the sampling planner's and the swarm layer's knobs.
    ``progress(message, fraction)`` is called as work proceeds. ``time_budget_s``: wall-clock
    budget of the optimiser (default ``RefineOptions.time_budget_s``), s. ``max_time_s``: wall-clock
    budget of the whole plan, s; a search still running then stops with :class:`PlanNotFound`
    ("not found within ..."), never with a different plan. ``sampling_alternative``: run the
    sampling planner beside the swarm layer (stage 3).
    """
    run = _start(method, seed, progress, options, swarm_options, time_budget_s, max_time_s)
    run = replace(run, alternative=sampling_alternative)
    scenario, assignment = _prepare(scenario, run)
    if run.swarm.reserve_starts is None:  # on with fixed goals, off where goals were assigned (SwarmOptions)
        run = replace(run, swarm=replace(run.swarm, reserve_starts=assignment is None))
    swarm = _swarm_stage(scenario, run) if _uses_swarm(run.method, scenario) else None
    plan = _sampling_stage(scenario, run, swarm)
    plan, swarm_info = refine_stage(
        scenario,
        plan,
        method=run.method,
        seed=run.seed,
        time_budget_s=run.time_budget_s,
        progress=run.progress,
        swarm_ran=swarm is not None,
        swarm_info=None if swarm is None else swarm.info,
        swarm_options=run.swarm,
        deadline=run.deadline,
    )
    _record(scenario, plan, run, swarm_info, assignment)
    if progress:
        progress("done", 1.0)
    return plan


# -- stage 0: the request ---------------------------------------------------------------------------
def _start(method, seed, progress, options, swarm_options, time_budget_s, max_time_s) -> _Run:
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    if time_budget_s is not None and not time_budget_s > 0:
        from proxplan.fileio import UserError

        raise UserError(f"--time-budget: expected a positive number of seconds, got {time_budget_s:g}")
    swarm = swarm_options or SwarmOptions()
    extra = OPTIMIZE_EXTRA_PASSES if method == "optimized" else 0
    t0 = time.perf_counter()
    return _Run(
        method=method,
        mode=MODE_OF_METHOD[method],
        seed=int(seed),
        sampling=options or SamplingOptions(),
        swarm=replace(swarm, seed=int(seed), passes=swarm.passes + extra),
        time_budget_s=time_budget_s,
        t0=t0,
        deadline=None if max_time_s is None else t0 + float(max_time_s),
        progress=progress,
    )


# -- stage 1: assignment and checks before any search -------------------------------------------
def _prepare(scenario: Scenario, run: _Run) -> tuple[Scenario, dict | None]:
    check_swarm_size(scenario)
    scenario, assignment = apply_assignment(scenario)
    check_starts_and_goals(scenario, mode=run.mode)
    check_goal_tubes(scenario, mode=run.mode)  # the verifier's rule: no planner's search margin
    if run.mode == "downwash":
        check_goal_loops(scenario)  # a hold where the vehicle's loop in the jets is not damped
    return scenario, assignment


def _uses_swarm(method: Method, scenario: Scenario) -> bool:
    """``swarm``, and ``optimized`` for a formation change: enough vehicles and no docks."""
    if method == "swarm":
        return True
    return method == "optimized" and len(scenario.vehicles) >= SWARM_MIN_VEHICLES and swarm_applicable(scenario) is None


# -- the one verification policy ----------------------------------------------------------------
def _until_verified(
    scenario: Scenario,
    run: _Run,
    attempt: Callable[[Mapping[str, float], int], Plan],
    seed_matters: Callable[[Plan], bool] | None = None,
) -> tuple[Plan, list]:
    """``attempt(deflections, seed)``'s plan and the verifier's violations of it (see module).
    ``seed_matters(plan)``: whether another seed could change that plan (None: always); when it
    could not, the attempt with another seed is not made (it would plan the same again)."""
    from proxplan.verify import verify_plan, verify_with_deflections

    plan = attempt({}, run.seed)
    bad, deflections = verify_with_deflections(plan, scenario, dt_fine_s=DEFLECTION_DT_S)
    if not bad:
        return plan, bad
    # the verifier's loops, not run again; none where it stopped before the model checks: predicted here
    grown = deflection_allowance(plan, scenario, deflections=deflections or None)
    tries = ([(grown, run.seed)] if grown else []) + [(grown, run.seed + RETRY_SEED_OFFSET)]
    last = plan  # the plan of the last attempt, planned with the deflections of the seed's retry
    for deflection, seed in tries:
        if seed != run.seed and seed_matters is not None and not seed_matters(last):
            plan.notes.append(f"another seed ({seed}) not tried: this plan does not depend on the seed")
            break
        again = attempt(deflection, seed)
        last = again
        bad_again = verify_plan(again, scenario)
        how = ", ".join(f"{n} {100 * d:.1f} cm" for n, d in sorted(deflection.items())) or "none"
        what = f"planned again (tubes grown by the predicted deflections: {how}; seed {seed})"
        if len(bad_again) < len(bad):
            again.notes.append(f"{what}: the first plan failed verification ({bad[0]})")
            plan, bad = again, bad_again
        else:
            plan.notes.append(f"{what}: no fewer violations")
        if not bad:
            break
    return plan, bad


# -- stage 2: the swarm layer -------------------------------------------------------------------
def _swarm_stage(scenario: Scenario, run: _Run) -> SwarmOutcome:
    why = swarm_applicable(scenario)
    if why is not None:
        return SwarmOutcome(None, None, f"swarm layer: not used, {why}", searched=False)
    infos: dict[int, SwarmInfo] = {}  # id(plan) -> the info of the attempt that made it
    gave_up: list[dict[str, float]] = []  # the deflections of the attempts whose prioritised planning gave up

    def attempt(deflection: Mapping[str, float], seed: int) -> Plan:
        grown = _merged(run.swarm.deflection_m, deflection)
        again = run.swarm.prioritized and not any(_no_narrower(before, grown) for before in gave_up)
        options = replace(run.swarm, seed=seed, deflection_m=grown, prioritized=again)
        timed, info = swarm_timed(scenario, options, progress=run.progress, deadline=run.deadline)
        if again and info.stage in ("lattice", "stacked"):  # prioritised planning ran and gave up
            gave_up.append(grown)
        plan = assemble_plan(scenario, timed, method=run.method, notes=list(scenario.load_notes))
        if run.swarm.prioritized and not again:
            plan.notes.append(
                "swarm layer: prioritised planning not run again (it gave up with keep-outs no wider; "
                "it does not draw on the seed)"
            )
        plan.notes.append(f"swarm layer: {info.coordination}")
        # only ``optimized``'s refine stage reads the hand-on (its problem, memo and give-up plans): any
        # other method frees it now, before the verifier and the next attempt run
        if run.method != "optimized" and getattr(info, "hand_on", None) is not None:
            info = replace(info, hand_on=None)
        infos[id(plan)] = info
        return plan

    try:
        # only the lattice's search draws on the seed (prioritised planning and re-timing do not; the
        # stacked plan's levels may use it)
        plan, bad = _until_verified(
            scenario, run, attempt, seed_matters=lambda p: infos[id(p)].stage in ("lattice", "stacked")
        )
    except PlanNotFound as err:
        if run.past_deadline():
            raise
        return SwarmOutcome(None, None, f"swarm layer: {err.message}")
    info = infos[id(plan)]
    if bad:
        return SwarmOutcome(None, info, f"swarm layer: plan failed verification ({bad[0]})")
    return SwarmOutcome(plan, info, None)


def _no_narrower(before: Mapping[str, float], now: Mapping[str, float]) -> bool:
    """Is every vehicle's deflection in ``now`` at least its deflection in ``before`` (m)? Then every
    pair's keep-out is at least as wide as before, and prioritised planning, which gave up with
    ``before`` (it does not draw on the seed), is not run again: with the same keep-outs it plans
    the same and gives up again (exact); wider keep-outs leave every vehicle no more room (not a
    proof that it gives up: a pass is not monotone in the keep-outs; issue 37 round 13B)."""
    return all(float(now.get(n, 0.0)) >= float(d) for n, d in before.items())


def _merged(a: Mapping[str, float], b: Mapping[str, float]) -> dict[str, float]:
    return {n: max(float(a.get(n, 0.0)), float(b.get(n, 0.0))) for n in set(a) | set(b)}


# -- stage 3: the sampling planner --------------------------------------------------------------
def _sampling_attempt(scenario: Scenario, run: _Run) -> Callable[[Mapping[str, float], int], Plan]:
    def attempt(deflection: Mapping[str, float], seed: int) -> Plan:
        options = replace(run.sampling, deflection_m=_merged(run.sampling.deflection_m, deflection))
        return sampling_plan(scenario, mode=run.mode, seed=seed, options=options, progress=run.progress)

    return attempt


def _sampling_stage(scenario: Scenario, run: _Run, swarm: SwarmOutcome | None) -> Plan:
    """The sampling planner's plan where there is no swarm plan (within the count budget of
    :func:`_counted` where the swarm layer searched and gave up: :class:`PlanNotFound` once spent);
    beside the swarm layer's lattice or prioritised plan (up to ``SAMPLING_ALTERNATIVE_MAX_VEHICLES``),
    within that budget, the shorter verified of the two; else the swarm plan."""
    if swarm is not None and swarm.plan is not None:
        searched = swarm.info is not None and swarm.info.stage != "straight"
        small = len(scenario.vehicles) <= SAMPLING_ALTERNATIVE_MAX_VEHICLES
        if run.alternative and searched and small and not run.past_deadline():
            return _shorter(scenario, run, swarm.plan)
        swarm.plan.verified = run.mode == "downwash"
        return swarm.plan
    if run.past_deadline():
        why = f" ({swarm.why_not})" if swarm is not None and swarm.why_not else ""
        raise PlanNotFound(f"no plan found within the time budget{why}")
    if swarm is not None and swarm.searched:  # the swarm layer gave up: a count budget, "not found" once spent
        run = replace(run, sampling=_counted(run.sampling, len(scenario.vehicles)))
    attempt = _sampling_attempt(scenario, run)
    if run.mode != "downwash":  # the baselines plan without the cut-offs: the verifier judges them, later
        plan, bad = attempt({}, run.seed), None
    else:
        plan, bad = _until_verified(scenario, run, attempt)
        if bad:
            plan.notes.append(f"still {len(bad)} violation(s) after planning again")
    if swarm is not None and swarm.why_not:
        budget = ""
        if swarm.searched:
            budget = (
                f" (count budget: {run.sampling.max_searches} single-vehicle searches of at most "
                f"{run.sampling.max_iterations} RRT iterations)"
            )
        plan.notes.append(f"{swarm.why_not}; this is the sampling planner's plan{budget}")
    plan.method = "sampling" if run.method in ("swarm", "optimized") else run.method
    plan.verified = bad == []
    return plan


def _counted(options: SamplingOptions, n_vehicles: int) -> SamplingOptions:
    """``options`` within the sampling planner's count budget beside or after the swarm layer:
    ``ALTERNATIVE_SEARCHES_PER_VEHICLE`` single-vehicle searches per vehicle over the whole plan
    (re-orderings included), each of at most ``ALTERNATIVE_RRT_ITERATIONS`` RRT iterations (a
    smaller budget passed in is kept)."""
    cap = ALTERNATIVE_SEARCHES_PER_VEHICLE * n_vehicles
    return replace(
        options,
        max_searches=cap if options.max_searches is None else min(options.max_searches, cap),
        max_iterations=min(options.max_iterations, ALTERNATIVE_RRT_ITERATIONS),
    )


def _shorter(scenario: Scenario, run: _Run, swarm_plan: Plan) -> Plan:
    """The swarm plan or, when shorter and verified, the sampling planner's plan within its count
    budget (:func:`_counted`).
    The sampling planner stops at the first vehicle it plans that arrives no earlier than the swarm
    plan's makespan (``SamplingOptions.beat_s``): the makespan of a plan holding that track could not
    be shorter. (Exact for its current order; the re-orderings it would make only after a later vehicle
    failed are not tried then, as they are not once its count budget is spent.)"""
    from proxplan.verify import verify_plan

    swarm_plan.verified = True
    mine = moving_end_s(swarm_plan)
    # it stops at the first vehicle that arrives no earlier: it could not be shorter
    budget = replace(_counted(run.sampling, len(scenario.vehicles)), beat_s=mine)
    try:
        other = _sampling_attempt(scenario, replace(run, sampling=budget))({}, run.seed)
    except (InfeasibleError, PlanNotFound) as err:
        swarm_plan.notes.append(f"the sampling planner was tried as well and found no shorter plan ({err})")
        return swarm_plan
    theirs = moving_end_s(other)
    if theirs >= mine or verify_plan(other, scenario):
        swarm_plan.notes.append(
            f"the sampling planner was tried as well (count budget): {theirs:.2f} s, not shorter or not verified"
        )
        return swarm_plan
    other.method = "sampling"
    other.verified = True
    other.notes.append(f"sampling planner's plan ({theirs:.2f} s): shorter than the swarm layer's ({mine:.2f} s)")
    return other


# -- stage 5: the record ------------------------------------------------------------------------
def _record(scenario: Scenario, plan: Plan, run: _Run, swarm: SwarmInfo | None, assignment: dict | None) -> None:
    """The stages' typed records into ``plan.metrics`` (one place; ``swarm``: what the swarm layer
    did for the swarm plan returned), then the DESIGN metrics."""
    plan.metrics["seed"] = run.seed
    if swarm is not None:
        plan.metrics["swarm"] = swarm.to_metrics()
        plan.metrics["lower_bound_s"] = swarm.lower_bound_s
    if assignment is not None:
        plan.metrics["assignment"] = assignment
        plan.metrics["assignment_lower_bound_s"] = assignment["lower_bound_s"]
    if plan.verified:
        plan.metrics["verify_violations"] = 0
    certified = certified_bound(scenario) if swarm is not None and assignment is None else None
    if certified is not None:  # fixed goals only: the bound is per vehicle's own goal
        plan.metrics["certified_lower_bound_s"] = certified.bound_s
        plan.metrics["certified_bound"] = asdict(certified)
    finish_metrics(scenario, plan, planning_time_s=time.perf_counter() - run.t0)
    if certified is not None and run.method == "optimized" and certified.bound_s > 0.0:
        ratio = moving_end_s(plan) / certified.bound_s
        plan.notes.append(
            f"optimized: the plan ({moving_end_s(plan):.2f} s) is {ratio:.2f}x the certified lower bound "
            f"({certified.bound_s:.2f} s, set by {certified.setter}: no plan can be shorter; docs/planner.md, "
            f"round 16A), within {100 * (ratio - 1.0):.1f} % of it"
        )
