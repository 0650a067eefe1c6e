"""``optimized`` for swarms: the makespan repair again, longer, on the kept plan's own tracks
(issue 37 item 6; used by :mod:`proxplan.planner.refine_stage`).

The fast plan runs the makespan repair (:func:`proxplan.planner.swarm.makespan.shorten_makespan`)
once, rest to rest (or through waypoints where the plan flies so), after re-timing. Measured first
(docs/planner.md, stop 60 round 22S): on the named layouts at 32 fixed the search ends by itself
(every neighbourhood of the latest vehicles skipped) well inside its budget, and what frees it is
the re-timing of the others: once they are re-timed through their waypoints, the latest vehicles'
neighbourhoods plan again into the time the others left (corridor-32 13.70 -> 12.53 s over three
rounds with the repair through waypoints too, 12.60 s without, in the bench; grid-32 7.55 -> 7.20 s in one). So here, in rounds, on the tracks the plan was made of
(:attr:`~proxplan.planner.swarm.info.SwarmHandOn.tracks`):

1. every vehicle re-timed through its waypoints along its straight line and its own route
   (:func:`proxplan.planner.swarm.retime.improve`, :data:`RETIME_PASSES` passes; never later);
2. the makespan repair, rest to rest (:data:`REPAIR_THROUGH`), within the fast plan's count budget
   (:func:`proxplan.planner.swarm.makespan.budget`) and its default stall budget.

A round that does not shorten the makespan ends the search; at most :data:`ROUNDS` rounds. Every
step keeps the tracks conflict-free against the others' and never makes the makespan longer, so the
result is never longer than the tracks given; the caller verifies it. Budgets are counts (passes,
plannings, rounds): the same seed gives the same plan on every machine; a wall-clock deadline stops
it only as "gave up" (the tracks at the start of that round are returned).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

from proxplan.planner.errors import PlanNotFound
from proxplan.planner.swarm.makespan import budget, shorten_makespan
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.plan import HORIZON_MARGIN_S
from proxplan.planner.swarm.problem import SwarmProblem
from proxplan.planner.swarm.retime import improve
from proxplan.planner.swarm.stage import own_routes
from proxplan.planner.swarm.tracks import GRID_DT_S, GridTrack

__all__ = ["REPAIR_THROUGH", "RETIME_PASSES", "ROUNDS", "LongerRepair", "longer_repair"]

# rounds of (re-timing, repair); the search ends earlier at the first round that does not shorten the
# makespan. Watched on the named layouts at 32 fixed (in-process, round 22S, with the repair through
# waypoints too): corridor-32 gained in rounds 1-3 (13.70 -> 13.03 -> 12.62 -> 12.53 s), nothing in round 4
# (+48 s of CPU for it); grid-32 gained in round 1 only; circle-32 and pillar-32 in none
ROUNDS = 3
# re-timing passes per round: the fast plan's own count (SwarmOptions.passes' default)
RETIME_PASSES = 3
# the repairs of a round, in turn: fly through waypoints (True) or rest to rest (False). Rest to rest only:
# in-process at 32 fixed (round 22S) the repair through waypoints after it shortened only corridor-32's third
# round (12.62 -> 12.53 s), nothing on grid, circle or pillar, and cost about as much CPU again (corridor: 91
# plannings, ~45 s, in its first round, for nothing)
REPAIR_THROUGH: tuple[bool, ...] = (False,)


@dataclass(frozen=True)
class LongerRepair:
    """What :func:`longer_repair` did: the tracks (agent -> track), the makespan before and after, s,
    one line per round, the single-vehicle plannings of the repairs and whether a deadline stopped it."""

    tracks: dict[int, GridTrack]
    makespan_before_s: float
    makespan_after_s: float
    rounds: tuple[str, ...]
    plannings: int
    gave_up: bool = False


def _makespan_s(tracks: dict[int, GridTrack]) -> float:
    return max(tr.arrival_s for tr in tracks.values())


def longer_repair(
    problem: SwarmProblem,
    tracks: dict[int, GridTrack],
    *,
    rounds: int = ROUNDS,
    retime_passes: int = RETIME_PASSES,
    deadline: float | None = None,
) -> LongerRepair:
    """The rounds of the module on a copy of ``tracks`` (conflict-free tracks of ``problem``, agent ->
    track); ``deadline``: time.perf_counter() value after which the search gives up (then the tracks
    at the start of the round running)."""
    by_agent = dict(tracks)
    before = _makespan_s(by_agent)
    lines: list[str] = []
    plannings = 0
    for k in range(rounds):
        start = dict(by_agent)
        was = _makespan_s(by_agent)
        horizon = int(round((was + HORIZON_MARGIN_S) / GRID_DT_S))
        try:
            occ = Occupancy(problem, list(by_agent.values()), horizon)
            chains = own_routes(problem, list(by_agent.values()))
            retimed = improve(occ, by_agent, chains, passes=retime_passes, through=True, deadline=deadline)
            mid = _makespan_s(by_agent)
            counts = [
                shorten_makespan(
                    problem,
                    by_agent,
                    horizon,
                    through=through,
                    max_plannings=budget(problem.n_agents),
                    deadline=deadline,
                )
                for through in REPAIR_THROUGH
            ]
        except PlanNotFound:
            lines.append(f"round {k + 1}: gave up (time budget), its start kept ({was:.2f} s)")
            return LongerRepair(start, before, _makespan_s(start), tuple(lines), plannings, gave_up=True)
        made = sum(c["plannings"] for c in counts)
        plannings += made
        now = _makespan_s(by_agent)
        lines.append(
            f"round {k + 1}: {was:.2f} s, re-timed {mid:.2f} s ({retimed['replaced']} tracks), repaired "
            f"{now:.2f} s ({sum(c['replaced'] for c in counts)} neighbourhoods, {made} plannings)"
        )
        if now >= was - 1e-9:
            break
    if deadline is not None and time.perf_counter() > deadline:
        lines.append("time budget spent after the last round")
    return LongerRepair(by_agent, before, _makespan_s(by_agent), tuple(lines), plannings)
