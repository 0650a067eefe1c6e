"""Holding points: a vehicle that must wait aside for another (issue 37, round 21B).

A vehicle whose start and goal both lie on another vehicle's route must leave its start before the
other passes it and reach its goal only after the other has passed that too. Its straight line can
wait only at its start or its goal (:func:`proxplan.planner.swarm.chain.time_chain` holds at
waypoints only); the wavefront route through the others' space-time (:mod:`proxplan.planner.swarm.wave`)
may wait aside, but on a coarse grid in a box round the line, and where it finds nothing the repair
may go round in a circle with the other vehicle (pillar-128: v009 and v120, docs/planner.md, stop 58
round 20B). Here the vehicle flies to a *holding point* beside its straight line, off the line by whole
reaches of the keep-out (:func:`holding_points`), and on to its goal: the chain start -> holding point ->
goal is timed exactly by the safe-interval search of :func:`~proxplan.planner.swarm.chain.time_chain`,
which waits at the holding point as long as the planned tracks require (:func:`plan_via_holding`).
Layout-free: the points come from the vehicle's own line, the keep-outs' reach and the static free space.
"""

from __future__ import annotations

import numpy as np

from proxplan.planner.swarm.chain import time_chain
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.tracks import GridTrack

# a holding point lies this many of the widest keep-out's horizontal reaches (SwarmProblem.reach_xy_m) off
# the vehicle's straight line: one reach clears a route along the line (the keep-out is at most that
# wide), two clear a neighbour holding beside it at one
HOLDING_REACHES = (1.0, 1.5, 2.0, 3.0)
# the points along the line a holding point is set beside: the start, the middle and the goal (fractions of
# the line): the vehicle must leave its start early (beside the start) or arrive late (beside the goal)
HOLDING_ALONG = (0.0, 0.25, 0.5, 0.75, 1.0)
# holding points timed per vehicle at most (the shortest detours of the 2 sides x HOLDING_REACHES x
# HOLDING_ALONG = 40 candidates, after those in an obstacle or never free): a count, so the same plan on
# every machine (an attempt is charged one planning of the pass, though it times up to this many chains)
MAX_HOLDING_POINTS = 12

__all__ = [
    "HOLDING_ALONG",
    "HOLDING_REACHES",
    "MAX_HOLDING_POINTS",
    "held_in_way",
    "holding_points",
    "plan_via_holding",
]


def holding_points(occ: Occupancy, agent: int) -> list[np.ndarray]:
    """Candidate holding points of ``agent`` (m, world frame): beside its straight line at
    :data:`HOLDING_ALONG`, :data:`HOLDING_REACHES` reaches off it horizontally on either side, where the
    point and the straight legs to it and on to the goal are statically free; the shortest detour first
    (ties: the order generated), at most :data:`MAX_HOLDING_POINTS`."""
    problem = occ.problem
    s, g = problem.starts_m[agent], problem.goals_m[agent]
    dxy = (g - s)[:2]
    length = float(np.linalg.norm(dxy))
    side = np.array([-dxy[1], dxy[0], 0.0]) / length if length > 1e-9 else np.array([0.0, 1.0, 0.0])
    reach = problem.reach_xy_m
    found: list[tuple[float, int, np.ndarray]] = []
    for f in HOLDING_ALONG:
        base = s + f * (g - s)
        for k in HOLDING_REACHES:
            for sign in (1.0, -1.0):
                h = base + sign * k * reach * side
                if not problem.static_free(h[None])[0] or occ.forbidden_holds(agent, h).all():
                    continue  # in an obstacle, or never free (a reserved start or a vehicle parked from t = 0)
                if not (problem.segment_free(s, h) and problem.segment_free(h, g)):
                    continue
                detour = float(np.linalg.norm(h - s) + np.linalg.norm(g - h))
                found.append((detour, len(found), h))
    found.sort(key=lambda x: (x[0], x[1]))
    return [h for _, _, h in found[:MAX_HOLDING_POINTS]]


def held_in_way(occ: Occupancy, agent: int, h_m: np.ndarray, held: set[int]) -> list[int]:
    """The vehicles of ``held`` (not planned yet, holding their starts) whose tracks in ``occ`` are in the
    way of ``agent``'s chain start -> ``h_m`` -> goal flown alone (timed against no one), sorted."""
    problem = occ.problem
    alone = time_chain(
        Occupancy(problem, [], occ.horizon), agent, np.array([problem.starts_m[agent], h_m, problem.goals_m[agent]])
    )
    if alone is None:
        return []
    return sorted(b for b in occ.conflicting_agents(alone.track) if b in held)


def plan_via_holding(occ: Occupancy, agent: int, through: bool) -> GridTrack | None:
    """The earliest-arriving track of ``agent`` through one of its :func:`holding_points` against the
    tracks in ``occ`` (start -> holding point -> goal, waiting at the holding point as long as needed),
    or None when none can be timed."""
    problem = occ.problem
    s, g = problem.starts_m[agent], problem.goals_m[agent]
    best = None
    for h in holding_points(occ, agent):
        res = time_chain(
            occ, agent, np.array([s, h, g]), arrive_by=None if best is None else best.arrival_step - 1, through=through
        )
        if res is not None and (best is None or res.arrival_step < best.arrival_step):
            best = res
    return None if best is None else best.track
