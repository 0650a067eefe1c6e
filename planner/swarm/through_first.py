"""Lines through an obstacle timed first, among themselves (issue 37 item 5, round 30B).

The passing stage (:mod:`~proxplan.planner.swarm.passes`) times a vehicle whose straight line leaves the
static free space late, round the obstacle, after the groups passing together and the straight lines. On
corridor-64 by type (``benchmarks/why_by_type.py``) two such lines cross the wall's gap in opposite
directions: v001 (1.19 B alone on its arc) is timed first and v002, timed after it and the others, is left a
corner chain arriving at 1.33 B, though alone on an arc it takes 0.94 B; v002 held 26 steps at its start
and then flown on an arc, or v001 held 8, both arrive within 1.3 B, and the others fit round them.

:func:`through_first`: where two of these lines' timings alone meet, each is timed
(:func:`~proxplan.planner.swarm.hemmed.late_track`: waits, corners, arcs, else a wavefront route), longest
line first, against the pinned vehicles and the lines timed before it only; the passing stage then places
the others round those tracks (exact against them, as every track of the stage).
"""

from __future__ import annotations

import numpy as np

from proxplan.planner.swarm.hemmed import late_track
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.problem import SwarmProblem
from proxplan.planner.swarm.straight import own_straight_track
from proxplan.planner.swarm.tracks import GridTrack

__all__ = ["THROUGH_FIRST", "through_first"]

# set on corridor-64 by type (round 30B: 1.34x -> 1.28x); where on, the passing stage runs twice where lines
# through an obstacle meet (pillar-64 by type: 12 such lines)
THROUGH_FIRST = True


def through_first(
    problem: SwarmProblem, horizon_steps: int, through: set[int], arrive_by: int | None
) -> dict[int, GridTrack] | None:
    """The tracks of the lines through an obstacle ``through`` timed among themselves (see module), each
    arriving by step ``arrive_by`` (None: any), where at least two of them, each timed alone against the
    pinned vehicles, meet; else None (also where one cannot be timed: the stage times them late as before)."""
    if not THROUGH_FIRST or len(through) < 2:
        return None
    pinned = [own_straight_track(problem, b) for b in range(problem.n_agents) if problem.pinned[b]]
    alone_occ = Occupancy(problem, pinned, horizon_steps)
    alone: dict[int, GridTrack] = {}
    for a in sorted(through):
        track = late_track(alone_occ, problem, a, arrive_by)
        if track is None:
            return None
        alone[a] = track
    if not any(
        Occupancy(problem, [alone[b]], horizon_steps).conflicting_agents(alone[a])
        for a in alone
        for b in alone
        if b > a
    ):
        return None
    length = np.linalg.norm(problem.goals_m - problem.starts_m, axis=1)
    occ = Occupancy(problem, pinned, horizon_steps)
    out: dict[int, GridTrack] = {}
    for a in sorted(through, key=lambda b: (-float(length[b]), b)):
        track = late_track(occ, problem, a, arrive_by)
        if track is None:
            return None
        out[a] = track
        occ.put(track)
    return out
