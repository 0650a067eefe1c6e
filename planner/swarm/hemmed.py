"""Late vehicles of the passing stage that the others hem in (issue 37 item 5, round 29S).

The passing stage (:mod:`~proxplan.planner.swarm.passes`) times the vehicles outside its groups one by one,
late (:func:`~proxplan.planner.swarm.yielding.time_yielding`: waits, corners, arcs), after the groups. Measured
on corridor-64 by type (``benchmarks/why_by_type.py``): its rows shuffle in rotations of three, and late
vehicles hem one another in (each one's goal beside another's start, both ways), so whichever is timed first
leaves the other no timing, and the stage gave up after its rounds. Two ways out, both exact against the
tracks placed (the caller checks every track as before):

* :func:`late_track`: where no line, corner or arc times a late vehicle, the single-vehicle planner's
  wavefront route round the tracks placed (:func:`~proxplan.planner.swarm.single.plan_one`);
* :func:`merged_group`: a late vehicle placed first and still hemmed in by late vehicles passes together
  with them, as a group of the stage, where that group has a joint move.
"""

from __future__ import annotations

from collections.abc import Callable

from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.problem import SwarmProblem
from proxplan.planner.swarm.single import plan_one
from proxplan.planner.swarm.tracks import GridTrack
from proxplan.planner.swarm.yielding import time_yielding

__all__ = ["LATE_ROUTE", "MERGE_HEMMING", "late_track", "merged_group"]

# both set on corridor-64 by type (round 29S: 1.90x -> 1.34x with both and the passing stage's 24 rounds;
# neither alone changes its plan); grid, circle and pillar at 64 keep their plans
LATE_ROUTE = True  # a late vehicle with no timing on its line, a corner or an arc flies a wavefront route
MERGE_HEMMING = True  # a late vehicle hemmed in by late vehicles passes together with them


def late_track(occ: Occupancy, problem: SwarmProblem, agent: int, arrive_by: int | None) -> GridTrack | None:
    """The earliest timing of the late ``agent`` against the tracks in ``occ`` arriving by step ``arrive_by``
    (None: any): :func:`time_yielding`'s, else (:data:`LATE_ROUTE`) the wavefront route's, else None."""
    best = time_yielding(occ, problem, agent, False, arrive_by)
    if best is not None:
        return best.track
    if not LATE_ROUTE:
        return None
    track = plan_one(occ, agent, True)
    if track is None or (arrive_by is not None and track.arrival_step > arrive_by):
        return None
    return track


def merged_group(
    problem: SwarmProblem,
    agent: int,
    hem: set[int],
    late: set[int],
    groups: list[tuple[int, ...]],
    has_move: Callable[[tuple[int, ...]], bool],
) -> tuple[int, ...] | None:
    """The group of the late ``agent`` (placed first and still hemmed in by ``hem``) and the late vehicles
    among ``hem`` (:data:`MERGE_HEMMING`), where there are any, none is pinned or flies a line through an
    obstacle (those are timed round it, never in a group), it is not among ``groups`` yet and ``has_move``
    (the stage's test: a joint move conflict-free among its members, as it is or staggered); else None."""
    if not MERGE_HEMMING:
        return None
    others = {b for b in hem if b in late and not problem.pinned[b]}
    if not others:
        return None
    group = tuple(sorted({agent} | others))
    if any(not problem.segment_free(problem.starts_m[a], problem.goals_m[a]) for a in group):
        return None
    if group in groups or not has_move(group):
        return None
    return group
