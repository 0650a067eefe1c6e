"""The pass with both wavefronts (``SwarmOptions.heights``), after re-timing in the swarm layer
(:mod:`proxplan.planner.swarm.plan`, stage 2): one more pass of prioritised planning
(:func:`~proxplan.planner.swarm.prioritised_stage.prioritised_stage`) with both wavefronts per vehicle
(:mod:`proxplan.planner.swarm.wave`, the earlier arrival kept), in the order and hold of the pass that
gave the plan, on what is left of the count budget; re-timed too, it replaces that plan only when it
is shorter (:func:`heights_pass`): a vehicle's earlier arrival can lengthen the whole plan. Whether it
runs: :func:`heights_on`.
"""

from __future__ import annotations

from collections.abc import Callable

from proxplan.planner.swarm.info import RetimeInfo
from proxplan.planner.swarm.occupancy import track_digest
from proxplan.planner.swarm.options import SwarmOptions
from proxplan.planner.swarm.prioritised_stage import prioritised_budget, prioritised_stage
from proxplan.planner.swarm.problem import SwarmProblem
from proxplan.planner.swarm.stage import Stage
from proxplan.planner.swarm.tracks import GridTrack

# SwarmOptions.heights None is on with fixed goals for at most this many vehicles: its pass costs about
# two plain passes (two wavefronts per planning), more where the wavefront spreads over long horizons.
# Whole processes, main / with it, one run each (docs/planner.md, round 12B; loaded): circle-128 30.5 ->
# 59.2 s of CPU (issue 37's 128 target is 60 s), circle-256 172 s -> past 362 s (target 300 s); at 64
# the 30 s target holds (pillar 14.7 -> 25.2 s, circle 8.8 -> 14.7 s). Set watching those named
# layouts, not the family: the largest size of the bench at which the time targets still hold
HEIGHTS_MAX_VEHICLES = 64

__all__ = ["HEIGHTS_MAX_VEHICLES", "heights_on", "heights_pass"]


def heights_on(opts: SwarmOptions, assigned: bool, n_agents: int, extra: dict) -> bool:
    """Whether the pass with both wavefronts runs on a plan of ``n_agents`` vehicles
    (``SwarmOptions.heights``; None: on with fixed goals, ``assigned`` False, up to
    ``HEIGHTS_MAX_VEHICLES``; why not is said in ``extra["heights"]``)."""
    heights = opts.heights
    if heights is None:
        heights = not assigned and n_agents <= HEIGHTS_MAX_VEHICLES
        if not assigned and not heights:
            extra["heights"] = f"both wavefronts: not planned (more than {HEIGHTS_MAX_VEHICLES} vehicles)"
    return heights


def heights_pass(
    problem: SwarmProblem,
    lower_bound_s: float,
    opts: SwarmOptions,
    found: Stage,
    by_agent: dict[int, GridTrack],
    extra: dict,
    retime: Callable[[Stage], tuple[dict[int, GridTrack], RetimeInfo]],
    *,
    progress,
    deadline,
) -> tuple[Stage, dict[int, GridTrack], RetimeInfo] | None:
    """``SwarmOptions.heights``: one more pass of prioritised planning, with both wavefronts per
    vehicle, in the order and hold of the pass that gave the plan without (``found``, already through
    its tail: ``by_agent``), on what is left of prioritised planning's count budget (a pass that
    cannot finish within it gives up early, charged the rest); re-timed as the plan without, that
    whole plan when it is shorter (then (stage, tracks, re-timing)), else None (the makespan repair
    runs after this choice, on the plan kept).
    No pass where prioritised planning did not give the plan (it gave up: its budget is spent; the
    lattice plan) or left no budget. What it gave is said in ``extra["heights"]``; its plannings are
    counted apart (``heights_planned``)."""
    without = max(tr.arrival_s for tr in by_agent.values())
    counts = extra.setdefault("counts", {})
    left = prioritised_budget(problem, opts) - counts.get("charged", 0)
    if found.pass_key is None or left <= 0:
        if found.stage == "lattice":
            why = "prioritised planning gave up: its budget spent"
        elif found.pass_key is None:
            why = "the plan with straight lines kept"
        else:
            why = "no planning budget left"
        extra["heights"] = f"both wavefronts: not planned ({why}); kept the plan without, {without:.2f} s"
        counts["heights_planned"] = 0
        return None
    mine: dict = {}
    alt = prioritised_stage(
        problem,
        lower_bound_s,
        opts,
        mine,
        progress=progress,
        deadline=deadline,
        heights=True,
        only=found.pass_key,
        budget=left,
    )
    counts["heights_planned"] = mine["counts"]["planned"]
    extra["heights_time_s"] = mine["prioritised_time_s"]
    if alt is None:
        extra["heights"] = f"both wavefronts: gave up ({mine['prioritised']}); kept the plan without, {without:.2f} s"
        return None
    same = found.stage == "prioritised" and all(
        track_digest(a) == track_digest(b) for a, b in zip(alt.tracks, found.tracks)
    )
    if same:
        extra["heights"] = f"both wavefronts: the same tracks as without ({mine['prioritised']})"
        return None
    alt_by_agent, retiming = retime(alt)
    makespan = max(tr.arrival_s for tr in alt_by_agent.values())
    keep = makespan < without
    extra["heights"] = (
        f"both wavefronts: {makespan:.2f} s ({mine['prioritised']}); without: {without:.2f} s ({found.stage}); "
        + ("kept both wavefronts" if keep else "kept the plan without")
    )
    if not keep:
        return None
    return alt, alt_by_agent, retiming
