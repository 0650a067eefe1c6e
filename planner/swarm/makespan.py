"""Shortening a conflict-free swarm plan where its makespan is set: the latest vehicle planned
again together with the vehicles in its way (a large-neighbourhood search, MAPF-LNS2, Li et al.
AAAI 2022: re-plan only a few agents, the others fixed).

Prioritised planning plans each vehicle against *predictions* of the vehicles not planned yet, and
re-timing (:mod:`proxplan.planner.swarm.retime`) moves one vehicle at a time along its own chains:
a vehicle that waits for another, or goes round one, keeps doing so although that other one could
have gone differently (grid-64 by_type: a 0.6 m line, 1.07 s alone, left at 1.70 s and set the
makespan). Here the vehicles are taken in order of decreasing arrival. For one of them, a, the
*neighbourhood* is first a alone (planned again against everyone else's tracks, one planning, once
per vehicle until some track changes; stop 57: on the stacked plan it leaves its level for the free
heights between the levels), then a and the vehicles whose tracks conflict with a's ideal track (its straight line
from t = 0, or its route round the obstacles: :func:`~proxplan.planner.swarm.priority.ideal_track`).
They are taken out and planned again one at a time (:func:`replan`:
:func:`~proxplan.planner.swarm.single.plan_one`, or its own route timed again, or its old track
where it still fits) against everyone else's final tracks, in two orders (a first; a last; an
order stops at the first vehicle that cannot arrive before the neighbourhood's latest before, and
that vehicle then goes first in one more order, once per vehicle: a raised priority, as in
priority-based search), when a vehicle of the neighbourhood arrives last of all (no other
neighbourhood can shorten the plan); the best result replaces them only when the latest arrival
in the neighbourhood gets strictly earlier. A neighbourhood spends at most
:data:`PLANNINGS_PER_VEHICLE` plannings per member (its orders stop there; corridor-64's latest
vehicle's neighbourhood of 14 took 103 plannings for nothing, stop 57), and none more once a member
cannot be planned even first (against the tracks outside the neighbourhood alone). Every new track is planned against all the others, so the plan
stays conflict-free and its makespan never grows. A vehicle whose neighbourhood gave nothing is
skipped until some neighbourhood is replaced (tracks changed). The budget is a count of
single-vehicle plannings (:data:`PLANNINGS_PER_VEHICLE` per vehicle), and it stops earlier once
:data:`STALL_WORK_STEPS` of work in a row (plannings x the horizon each searches, in grid steps:
a planning's cost grows with its horizon, stop 59) have not made the plan's latest arrival
earlier (:data:`STALL_ON_MAKESPAN`; until round 29B: replaced nothing), so a seed gives
the same plan on every machine; a wall-clock deadline stops it only as "not found".
"""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Callable

import numpy as np

from proxplan.planner.errors import PlanNotFound
from proxplan.planner.swarm.chain import time_chain
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.priority import ideal_track, plan_one
from proxplan.planner.swarm.problem import SwarmProblem
from proxplan.planner.swarm.tracks import GRID_DT_S, GridTrack
from proxplan.planner.timing.profile import rest_to_rest

# single-vehicle plannings of the whole search, per vehicle (the unit of prioritised planning's own
# budget, SwarmOptions.plannings_per_vehicle = 6): one is what one pass of prioritised planning
# costs. 1 until stop 56 (a prototype on grid-64 by_type with 60 and 80 plannings gave the same
# makespan); 3 since the neighbourhoods are planned in more orders (a vehicle that cannot be
# planned goes first): chosen watching grid-32, pillar-64 and circle-64 fixed in-process with 1, 3
# and 6 (6 took pillar-64's repair to 30 s of CPU alone, the issue's whole target; docs/planner.md,
# stop 56 round 18C)
PLANNINGS_PER_VEHICLE = 3.0
# the search stops once this much WORK in a row has replaced nothing: plannings x the horizon they
# search, in grid steps (a planning's CPU grows with its horizon: ~0.05 s at grid-64's 477 steps,
# ~0.35 s at grid-256's 1885; docs/planner.md, stop 59 round 21A). 96 plannings at grid-128's
# horizon of 720 steps: round 20A set the stall to 96 plannings watching the named layouts (the
# longest run of plannings before a gain of the makespan: grid-64 48, grid-128 81, circle-64 61,
# corridor-64 and pillar-64 2); counted in work the budget no longer grows with N^2 (the plannings
# x the horizon): grid-64 gets 144 plannings, corridor-64 (1123 steps) 61, grid-128 96, grid-256 36
STALL_WORK_STEPS = 96 * 720
# what restarts the stall count (STALL_WORK_STEPS): True (round 29B) only a replacement that makes the
# plan's latest arrival earlier, False (until round 29B) any replacement, also a vehicle planned again
# alone while others still arrive as late. Corridor-128's stacked plan has 10 vehicles arriving last
# together: 4 of them replaced alone restarted the count 4 times, 150 plannings (57 s of CPU), and the
# makespan stayed 39.475 s. Not exact (a later neighbourhood could have shortened it): kept because no
# named-layout plan got longer (docs/planner.md, stop 67 round 29B)
STALL_ON_MAKESPAN = True
# whether a track planned again may be taken, against the tracks in the occupancy: (occupancy, the
# track, the vehicle's track before the repair planned it again or None) -> bool
Fits = Callable[[Occupancy, GridTrack, GridTrack | None], bool]
__all__ = [
    "PLANNINGS_PER_VEHICLE",
    "STALL_ON_MAKESPAN",
    "STALL_WORK_STEPS",
    "budget",
    "replan",
    "shorten_makespan",
    "stall_budget",
]


def shorten_makespan(
    problem: SwarmProblem,
    by_agent: dict[int, GridTrack],
    horizon_steps: int,
    *,
    through: bool,
    max_plannings: int,
    stall_plannings: int | None = None,
    deadline: float | None = None,
    fits: Fits | None = None,
    stall_on_makespan: bool | None = None,
) -> dict[str, int]:
    """Replace neighbourhoods of ``by_agent`` (agent -> track, conflict-free; changed in place) as
    long as they shorten (see module), within ``max_plannings`` single-vehicle plannings over the
    ``horizon_steps`` grid, stopping once ``stall_plannings`` plannings in a row replaced nothing
    (None: :func:`stall_budget` of the horizon, :data:`STALL_WORK_STEPS` of work);
    ``through``: fly through waypoints (else rest to rest). ``fits`` (None: every track): whether a
    track planned again may be taken (:func:`replan`; on the stacked plan
    :meth:`~proxplan.planner.swarm.verify_guard.VerifyGuard.fits`: the verifier's sums of jets, which
    the pair keep-outs do not see). Returns the counts: ``plannings``, ``replaced`` (neighbourhoods),
    ``tried`` (neighbourhoods), ``solo`` (vehicles alone replaced)."""
    if stall_plannings is None:
        stall_plannings = stall_budget(horizon_steps)
    if stall_on_makespan is None:
        stall_on_makespan = STALL_ON_MAKESPAN
    plan_again = replan if fits is None else functools.partial(replan, fits=fits)
    occ = Occupancy(problem, list(by_agent.values()), horizon_steps)
    alone = {  # each vehicle's straight line alone, rest to rest, in steps: nothing arrives earlier
        a: rest_to_rest(
            float(np.linalg.norm(problem.goals_m[a] - problem.starts_m[a])), problem.limits[a], GRID_DT_S
        ).steps
        for a in by_agent
    }
    counts = {"plannings": 0, "replaced": 0, "tried": 0, "solo": 0}
    skip: set[int] = {a for a in by_agent if problem.pinned[a]}
    solo_tried: set[int] = set()  # planned alone since the tracks last changed
    gained = 0  # the count of plannings at the last gain (STALL_ON_MAKESPAN; or at the start)
    latest = max(t.arrival_step for t in by_agent.values())  # the plan's latest arrival at the last gain

    def gain() -> None:
        nonlocal gained, latest
        now = max(t.arrival_step for t in by_agent.values())
        if not stall_on_makespan or now < latest:
            gained, latest = counts["plannings"], now

    while counts["plannings"] < min(max_plannings, gained + stall_plannings):
        if deadline is not None and time.perf_counter() > deadline:
            raise PlanNotFound("no plan found within the time budget (makespan repair)")
        order = sorted((a for a in by_agent if a not in skip), key=lambda a: (-by_agent[a].arrival_step, a))
        if not order:
            break
        a = order[0]
        if not _may_meet_the_last(problem, by_agent, a):
            skip.add(a)  # no vehicle that arrives last can be in its way: nothing to gain
            continue
        end = max(t.arrival_step for t in by_agent.values())
        if a not in solo_tried and by_agent[a].arrival_step == end > alone[a]:
            solo_tried.add(a)  # the neighbourhood of a alone first: one planning, the others kept
            occ.remove(a)
            track = plan_again(occ, a, by_agent[a], end, through)
            counts["plannings"] += 1
            occ.put(track if track is not None else by_agent[a])
            if track is not None:
                by_agent[a] = track
                counts["replaced"] += 1
                counts["solo"] += 1
                gain()
                skip = {b for b in by_agent if problem.pinned[b]}
                solo_tried.clear()
                continue
        ideal = ideal_track(problem, occ, a)
        way = occ.conflicting_agents(ideal) - {a} if ideal is not None else set()
        others = sorted((b for b in way if not problem.pinned[b]), key=lambda b: (-by_agent[b].arrival_step, b))
        group = [a, *others]
        worst = max(by_agent[b].arrival_step for b in group)
        last = [b for b in group if by_agent[b].arrival_step == worst]
        if worst < max(t.arrival_step for t in by_agent.values()) or all(worst <= alone[b] for b in last):
            skip.add(a)  # it cannot shorten the plan: not the last of all, or the last already as early as alone
            continue
        old = {b: occ.remove(b) for b in group}
        best: dict[int, GridTrack] | None = None
        counts["tried"] += 1
        orders = [group, [*others, a]] if others else [group]
        promoted: set[int] = set()
        # a neighbourhood spends at most the whole search's unit per member (PLANNINGS_PER_VEHICLE),
        # and nothing past the stall budget (stall_plannings since the last gain)
        until = min(
            max_plannings,
            gained + stall_plannings,
            counts["plannings"] + math.ceil(PLANNINGS_PER_VEHICLE * len(group)),
        )
        while orders:
            seq = orders.pop(0)
            if counts["plannings"] + len(seq) > until:
                break
            new: dict[int, GridTrack] = {}
            stuck = None
            for b in seq:
                track = plan_again(occ, b, old[b], worst, through)
                counts["plannings"] += 1
                if track is None:  # this order cannot shorten the neighbourhood
                    stuck = b
                    break
                new[b] = track
                occ.put(track)
            for b in new:
                occ.remove(b)
            if len(new) == len(group) and (best is None or _latest(new) < _latest(best)):
                best = new
            if stuck is not None and stuck == seq[0]:
                break  # not even planned first (against the tracks outside alone): no order plans it
            if best is None and stuck is not None and stuck not in promoted:
                promoted.add(stuck)  # its priority raised: planned first in one more order
                orders.insert(0, [stuck, *(b for b in seq if b != stuck)])
        if best is not None and _latest(best) < worst:
            by_agent.update(best)
            for track in best.values():
                occ.put(track)
            counts["replaced"] += 1
            gain()
            skip = {b for b in by_agent if problem.pinned[b]}
            solo_tried.clear()
            continue
        for track in old.values():
            if track is not None:
                occ.put(track)
        skip.add(a)
    return counts


def replan(
    occ: Occupancy, b: int, old: GridTrack | None, worst: int, through: bool, fits: Fits | None = None
) -> GridTrack | None:
    """A track of ``b`` against the tracks in ``occ`` arriving before step ``worst``, or None: the
    earlier of :func:`~proxplan.planner.swarm.single.plan_one` and ``old``'s own route (the waypoint
    chain it was timed along, where it has more than two points) timed again, else ``old`` itself
    where it arrives in time and still conflicts with no track in ``occ``. ``plan_one`` alone does
    not always find a track where one exists (docs/planner.md, stop 56: on pillar-64 it found none
    for two of the four latest vehicles against everyone else's tracks, though their own exist).
    ``fits`` (None: every track): a track it refuses is not taken, the next of those three is; it is
    asked only about a track that would be taken (:func:`_fitting`)."""
    track = plan_one(occ, b, through, arrive_by=worst - 1)  # a later track is never taken (round 37B)
    route = None if old is None else old.route_m
    timed = route is not None and len(route) > 2
    if fits is not None:
        track = _fitting(occ, b, old, worst, through, fits, track, route if timed else None)
    elif route is not None and timed:
        res = time_chain(occ, b, route, arrive_by=_before(track, worst), through=through)
        if res is not None and (track is None or res.arrival_step < track.arrival_step):
            track = res.track
    if (track is None or track.arrival_step >= worst) and old is not None and old.arrival_step < worst:
        if not occ.conflicting_agents(old) and (fits is None or fits(occ, old, old)):
            track = old
    return None if track is None or track.arrival_step >= worst else track


def _fitting(
    occ: Occupancy,
    b: int,
    old: GridTrack | None,
    worst: int,
    through: bool,
    fits: Fits,
    found: GridTrack | None,
    route: np.ndarray | None,
) -> GridTrack | None:
    """:func:`replan`'s choice between ``found`` (plan_one's track) and ``route`` timed again (None: not
    timed) under ``fits``, before the fall-back to the old track; ``fits`` asked only where its answer
    decides: the same track as asking about ``found`` first (then timing the route to arrive before
    it where ``fits`` takes it, and at all where it refuses it), asking about the route's track where
    that is earlier, then taking the earlier one that fits (stop 61 round 23A: corridor-64's guard
    built a sub-plan for every track planned, also for a track arriving too late to be taken or
    beaten by the route's). Exact because: a track arriving at or after ``worst`` is never returned
    (the old track or None follows whatever ``fits`` says of it); and the route's earliest timing is
    the same track whether or not its search is told to arrive before ``found`` (:func:`time_chain`'s
    ``arrive_by`` only prunes what arrives later), so asking for it with ``arrive_by`` gives the
    track the search without it gives whenever that one arrives earlier than ``found``."""
    if found is None:
        if route is None:
            return None
        res = time_chain(occ, b, route, arrive_by=worst - 1, through=through)
        return res.track if res is not None and fits(occ, res.track, old) else None
    if route is not None:
        res = time_chain(occ, b, route, arrive_by=_before(found, worst), through=through)
        if res is not None and fits(occ, res.track, old):
            return res.track  # earlier than found, and taken whatever fits says of found
        if res is None:  # nothing earlier than found on the route
            if found.arrival_step >= worst:
                return None
            if fits(occ, found, old):
                return found
            # found refused: the route timed with no bound (it arrives no earlier than found)
            res = time_chain(occ, b, route, arrive_by=worst - 1, through=through)
            return res.track if res is not None and fits(occ, res.track, old) else None
    if found.arrival_step >= worst:
        return None  # never taken: the old track or none follows, whatever fits says
    return found if fits(occ, found, old) else None


def _before(found: GridTrack | None, worst: int) -> int:
    """The last grid step a route's timing in :func:`replan` may arrive at and matter: before ``found``
    (plan_one's track; None: none) and before ``worst``."""
    return worst - 1 if found is None else min(found.arrival_step, worst) - 1


def _may_meet_the_last(problem: SwarmProblem, by_agent: dict[int, GridTrack], a: int) -> bool:
    """False only when no track of a vehicle arriving last can be in the way of ``a``'s ideal track
    (an exact filter before that track is built): ``a`` does not arrive last itself, its straight
    line is statically free (then the ideal track stays in the box of its start and goal) and that
    box grown by the keep-outs' reach misses the box of every last track."""
    end = max(t.arrival_step for t in by_agent.values())
    if by_agent[a].arrival_step == end:
        return True
    s, g = problem.starts_m[a], problem.goals_m[a]
    if not problem.segment_free(s, g):  # its ideal track is a route round the obstacles: anywhere
        return True
    grow = np.array([problem.reach_xy_m, problem.reach_xy_m, problem.reach_z_m])
    lo, hi = np.minimum(s, g) - grow, np.maximum(s, g) + grow
    return any(bool(np.all(lo <= t.hi_m) and np.all(hi >= t.lo_m)) for t in by_agent.values() if t.arrival_step == end)


def _latest(tracks: dict[int, GridTrack]) -> int:
    return max(t.arrival_step for t in tracks.values())


def stall_budget(horizon_steps: int, work_steps: int = STALL_WORK_STEPS) -> int:
    """Plannings in a row without a gain after which the search stops: ``work_steps`` of work
    (plannings x ``horizon_steps``, the grid steps each planning searches), at least one."""
    return max(1, work_steps // max(1, horizon_steps))


def budget(n_agents: int) -> int:
    """Single-vehicle plannings of the whole search for ``n_agents`` vehicles."""
    return math.ceil(PLANNINGS_PER_VEHICLE * n_agents)
