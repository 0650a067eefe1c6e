"""The re-timing stage of the swarm layer (:mod:`proxplan.planner.swarm.plan`, stage 4): a stage's
tracks re-timed by Gauss-Seidel passes (:mod:`proxplan.planner.swarm.retime`) over a horizon a
margin past its makespan; never worse, always conflict-free. Grid steps of
:data:`~proxplan.planner.swarm.tracks.GRID_DT_S`, s."""

from __future__ import annotations

import time

from proxplan.planner.swarm.info import RetimeInfo
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.options import SwarmOptions
from proxplan.planner.swarm.problem import SwarmProblem
from proxplan.planner.swarm.retime import improve
from proxplan.planner.swarm.stage import Stage
from proxplan.planner.swarm.tracks import GRID_DT_S, GridTrack

HORIZON_MARGIN_S = 5.0  # the re-timing horizon extends this far past the initial makespan, s

__all__ = ["HORIZON_MARGIN_S", "retime_stage"]


def retime_stage(
    problem: SwarmProblem, found: Stage, initial_s: float, opts: SwarmOptions, *, progress, deadline
) -> tuple[dict[int, GridTrack], RetimeInfo]:
    """Gauss-Seidel re-timing of every vehicle along its chains (never worse, conflict-free)."""
    by_agent = {tr.agent: tr for tr in found.tracks}
    horizon = int(round((initial_s + HORIZON_MARGIN_S) / GRID_DT_S))
    occ = Occupancy(problem, found.tracks, horizon)
    t2 = time.perf_counter()
    counts = improve(
        occ,
        by_agent,
        found.routes,
        passes=opts.passes,
        through=opts.through_waypoints != "never",
        progress=progress,
        deadline=deadline,
    )
    return by_agent, RetimeInfo(**counts, time_s=round(time.perf_counter() - t2, 3))
