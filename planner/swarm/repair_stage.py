"""The makespan repair stage of the swarm layer (:mod:`proxplan.planner.swarm.plan`, stage 5): whether
it runs on a plan (:func:`repairs`) and the repair itself on the plan kept (:func:`makespan_stage`,
:mod:`proxplan.planner.swarm.makespan`), guarded on the stacked plan by the verifier's sums of jets
(:class:`~proxplan.planner.swarm.verify_guard.VerifyGuard`). Grid steps of
:data:`~proxplan.planner.swarm.tracks.GRID_DT_S`, s."""

from __future__ import annotations

import time

from proxplan.planner.swarm.info import MakespanRepairInfo
from proxplan.planner.swarm.makespan import budget as makespan_budget
from proxplan.planner.swarm.makespan import shorten_makespan
from proxplan.planner.swarm.options import SwarmOptions
from proxplan.planner.swarm.problem import SwarmProblem
from proxplan.planner.swarm.retime_stage import HORIZON_MARGIN_S
from proxplan.planner.swarm.stage import Stage
from proxplan.planner.swarm.tracks import GRID_DT_S, GridTrack
from proxplan.planner.swarm.verify_guard import Check, VerifyGuard

__all__ = ["makespan_stage", "repairs"]


def repairs(opts: SwarmOptions, found: Stage) -> bool:
    """Whether the makespan repair runs on the plan of ``found`` (``SwarmOptions.makespan_repair``;
    None: not on the lattice plan (lock-step tracks: nothing replaced on grid-64 and corridor-64 fixed,
    round 14A), on elsewhere. On the stacked plan it shortens grid-64 6.93 -> 5.58 s and grid-128 13.00
    -> 11.50 s; it was off there after stop 58 (grid-256 past 500 s of CPU): there its repaired plan
    failed verify (a vehicle flown between the levels adds its jet to the level above's on a vehicle
    below) and the pipeline planned again; now its result on the stacked plan is verified and given up
    where it fails, and its stall budget is counted in work (``makespan.STALL_WORK_STEPS``; round 21A)."""
    if opts.makespan_repair is not None:
        return opts.makespan_repair
    return found.stage != "lattice"


def makespan_stage(
    problem: SwarmProblem,
    by_agent: dict[int, GridTrack],
    opts: SwarmOptions,
    *,
    progress,
    deadline,
    check: Check | None = None,
) -> MakespanRepairInfo:
    """The latest vehicles planned again with those in their way (:mod:`proxplan.planner.swarm.makespan`;
    ``by_agent`` changed in place; never longer, always conflict-free). ``check`` (the stacked plan:
    :class:`~proxplan.planner.swarm.verify_guard.VerifyGuard`): the repair plans against the pair
    keep-outs, and a vehicle it flies between the stacked plan's levels can add its jet to the level
    above's on a vehicle below (the levels are stacked so that two sources fit, levels.STACK_AUTHORITY_SHARE;
    grid-256: 0.119 of the 0.1 authority fraction, stop 59 round 21A), so such a track is taken only
    where the verifier's sums pass around it (``VerifyGuard.fits``); the whole result is asked once
    more after the repair replaced tracks, and where that fails the tracks before the repair come back
    (``MakespanRepairInfo.verify_failed``)."""
    before = max(tr.arrival_s for tr in by_agent.values())
    kept = dict(by_agent)
    if progress:
        progress("makespan repair", 0.9)
    t0 = time.perf_counter()
    counts = shorten_makespan(
        problem,
        by_agent,
        int(round((before + HORIZON_MARGIN_S) / GRID_DT_S)),
        through=opts.through_waypoints == "always",
        max_plannings=makespan_budget(problem.n_agents),
        deadline=deadline,
        fits=check.fits if isinstance(check, VerifyGuard) else None,
    )
    failed = check is not None and counts["replaced"] > 0 and not check(by_agent)
    if failed:
        by_agent.update(kept)
    return MakespanRepairInfo(
        makespan_before_s=before,
        makespan_after_s=max(tr.arrival_s for tr in by_agent.values()),
        time_s=round(time.perf_counter() - t0, 3),
        verify_failed=failed,
        refused=check.refused if isinstance(check, VerifyGuard) else 0,
        **counts,
    )
