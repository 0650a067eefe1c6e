"""The goal block filled from its far side: a planning order for prioritised planning derived from the
start/goal geometry and the obstacles (issue 37, round 24B).

Each vehicle's *route* is the track it would fly alone (:func:`proxplan.planner.swarm.reserve.ideal_track`:
its straight line, or its route through the static free space round the obstacles). Two relations are
read off the routes, each with the keep-out of the pair's types (an :class:`Occupancy` query, the same
test as the planner's):

* a's route **passes b's goal** (comes within keep-out of b parked at its goal at some time): b's goal
  lies in front of a's, nearer the incoming stream, so a is planned (and flies) before b, and b fills
  its slot after a has passed. Vehicles whose goals no route passes (the far side of the goal block)
  come first; the front rows of the goal block, passed by many routes, come last;
* a's start **blocks** b's route (b's route comes within keep-out of a resting at its start): a has to
  leave before b passes; among the vehicles the first relation leaves free, the one whose start blocks
  the most routes is planned first.

Order (:func:`fill_order`): a topological order of the first relation (Kahn), ties among the vehicles
ready by (most routes their start blocks, the longer route first, index); where a cycle leaves nobody
ready, the vehicle with the fewest predecessors not yet placed goes next (same ties). Everything is a
function of the scenario, so the same scenario gives the same order.
"""

from __future__ import annotations

import numpy as np

from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.problem import SwarmProblem
from proxplan.planner.swarm.reserve import ideal_track, starts_in_the_way
from proxplan.planner.swarm.tracks import GRID_DT_S, GridTrack

# horizon of the routes flown alone, s: far above any of the named layouts' (the longest at 64, corridor's
# 8.2 m round the wall, flies in under 5 s: its bound is 4.75 s); a vehicle with no route within it
# (ideal_track None) passes no goal and its start blocks no route
ROUTE_HORIZON_S = 60.0

__all__ = ["ROUTE_HORIZON_S", "RouteRelations", "fill_order", "route_relations"]


class RouteRelations:
    """Per vehicle: ``passes[a]`` the goals a's route passes, ``blocks[a]`` the routes a's start blocks
    (both sets of vehicle indices, a excluded), ``length_m[a]`` the length of a's route (m)."""

    def __init__(self, passes: dict[int, set[int]], blocks: dict[int, set[int]], length_m: np.ndarray):
        self.passes, self.blocks, self.length_m = passes, blocks, length_m


def _route_length_m(problem: SwarmProblem, agent: int, track: GridTrack | None) -> float:
    if track is None or not track.moves:
        return float(np.linalg.norm(problem.goals_m[agent] - problem.starts_m[agent]))
    length, at = 0.0, problem.starts_m[agent]
    for _, mv in track.moves:
        length += float(np.linalg.norm(mv.end_m - at))
        at = mv.end_m
    return length


def route_relations(problem: SwarmProblem) -> RouteRelations:
    """The two relations of the module read off each vehicle's route flown alone."""
    A = problem.n_agents
    horizon = int(round(ROUTE_HORIZON_S / GRID_DT_S))
    ideal = {a: ideal_track(problem, a, horizon) for a in range(A)}
    parked = [GridTrack(a, int(problem.type_index[a]), problem.goals_m[a].copy(), []) for a in range(A)]
    goals = Occupancy(problem, parked, horizon)
    passes = {a: (set() if tr is None else goals.conflicting_agents(tr) - {a}) for a, tr in ideal.items()}
    starts_on = starts_in_the_way(problem, ideal, horizon)  # b -> the starts b's route passes
    blocks: dict[int, set[int]] = {a: set() for a in range(A)}
    for b, on in starts_on.items():
        for a in on:
            blocks[a].add(b)
    length = np.array([_route_length_m(problem, a, ideal[a]) for a in range(A)])
    return RouteRelations(passes, blocks, length)


def fill_order(problem: SwarmProblem, relations: RouteRelations | None = None) -> list[int]:
    """Planning order: the goal block filled from its far side (see module)."""
    rel = route_relations(problem) if relations is None else relations
    A = problem.n_agents
    before: dict[int, set[int]] = {a: set() for a in range(A)}  # b -> vehicles to place before b
    for a, passed in rel.passes.items():
        for b in passed:
            before[b].add(a)
    key = {a: (-len(rel.blocks[a]), -float(rel.length_m[a]), a) for a in range(A)}
    out: list[int] = []
    done: set[int] = set()
    while len(out) < A:
        left = [a for a in range(A) if a not in done]
        ready = [a for a in left if before[a] <= done]
        pick = min(ready, key=key.__getitem__) if ready else min(left, key=lambda a: (len(before[a] - done), key[a]))
        out.append(pick)
        done.add(pick)
    return out
