"""Prioritised planning in continuous time with repair of only the vehicles in conflict.

One vehicle after another is planned against the tracks in the
:class:`~proxplan.planner.swarm.occupancy.Occupancy` (its space-time hash: only tracks within reach
are looked at; :mod:`proxplan.planner.swarm.single`). Each tries its candidate waypoint chains - the straight line and the wavefront route
through the others' space-time (:func:`proxplan.planner.swarm.wave.wave_route`), then a slower,
wider route - timed exactly, flying through waypoints where it can
(:func:`proxplan.planner.swarm.chain.time_chain`), and keeps the earliest arrival.

**Vehicles not planned yet.** Each is assumed to leave at once on its straight route: its
*predicted* track flies the straight line from t = 0 (after ``hold_s``) and vanishes once it is out
of reach of its start (it does not park), so the vehicles planned before it keep its start clear
only while it leaves. When it is planned itself, its real track replaces the prediction. A
prediction is an assumption, not a plan: a vehicle that cannot be planned around the predictions in
the way of its ideal track is planned once more without them. With ``reserve_starts``
(:mod:`proxplan.planner.swarm.reserve`) a vehicle not planned yet holds its start for good instead;
a vehicle that cannot be planned around the reserved starts in the way of its ideal track is planned
once more with those released (predicted to leave), and they are planned next, the one it reaches
first first, before anyone else relies on their leaving.

**Repair (MAPF-LNS2, Li et al. AAAI 2022: re-plan only the agents in conflict).** When a vehicle
cannot be planned, the planned vehicles whose tracks conflict with its ideal track (its straight
line from t = 0, or its route through the static free space) are taken out (their predictions come
back), the vehicle is planned first, then they are planned again, in their order. A repair puts the
vehicle before them (a partial order, kept transitive, as in priority-based search), so repairs
do not go round in circles while the order allows one. When it does not (every vehicle in the
way must go before it, by an earlier repair), the repair goes against the order: those vehicles
are taken out all the same and the vehicle goes before them from now on (the earlier repair that
put them first is undone for these pairs) - only these vehicles are planned again, never the
whole pass. When nothing planned is in the way of its ideal track (only predictions of vehicles
not planned yet), it flies that track: it is clear of every planned track. Every repair is
counted; ``max_repairs`` (a count, per pass) bounds them, ``max_plannings`` the single-vehicle
plannings of the pass. A vehicle still failing then (repairs spent, nobody to take out, or the
same reversal again) is planned through a holding point beside its line where ``holding`` is on
(:mod:`proxplan.planner.swarm.holding`; off by default), else flies in collision with only the vehicles in its way (planned against all the
others; its ideal track if even that fails), the pass goes on, and at its end the collisions are
repaired a neighbourhood at a time (:mod:`proxplan.planner.swarm.lns`, within
:data:`LNS_PLANNINGS_PER_VEHICLE` plannings per vehicle); collisions still left give the pass up, and so
does a vehicle in collision beyond ``max_in_collision`` (:func:`in_collision_cap`), at once
(:class:`PrioritizedFailed`: the caller falls back; ``collisions=False`` gives it up at once, as before). A caller's wall-clock
``deadline`` only ever stops it as "not found" (:class:`~proxplan.planner.errors.PlanNotFound`).

Order (:func:`~proxplan.planner.swarm.priority_order.dependency_order`): a vehicle whose start another one's
goal needs is planned first (it must leave before the other arrives); otherwise, and to break cycles, the longer
straight line first. What a pass is asked and hands back (:class:`PriorityOptions`, :class:`PriorityResult`,
:class:`PrioritizedFailed`) is :mod:`proxplan.planner.swarm.priority_options`.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable, Iterable

import numpy as np

from proxplan.planner.errors import PlanNotFound
from proxplan.planner.swarm.chain import time_chain
from proxplan.planner.swarm.holding import held_in_way, holding_points, plan_via_holding
from proxplan.planner.swarm.lns import NEIGHBOURHOOD, remove_collisions
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.priority_options import PrioritizedFailed, PriorityOptions, PriorityResult
from proxplan.planner.swarm.priority_order import dependency_order
from proxplan.planner.swarm.problem import SwarmProblem
from proxplan.planner.swarm.raised import raised_or
from proxplan.planner.swarm.reserve import Reservations, predicted_track, reserved_track
from proxplan.planner.swarm.single import ideal_track, plan_ignoring, plan_one, start_visitors
from proxplan.planner.swarm.tracks import GridTrack

# the collision repair's plannings per vehicle of the pass, at most: a whole pass costs 2-3 per vehicle
# on the named layouts at 64 fixed (docs/planner.md), so the repair may cost up to half a pass more
# before the next order is tried (set watching those figures, not the randomised family)
LNS_PLANNINGS_PER_VEHICLE = 1


def in_collision_cap(n_vehicles: int) -> int:
    """Vehicles a pass may leave in collision before it gives up (``PriorityOptions.max_in_collision``):
    as many as the collision repair has full neighbourhoods in its count, ``LNS_PLANNINGS_PER_VEHICLE``
    x ``n_vehicles`` plannings / :data:`~proxplan.planner.swarm.lns.NEIGHBOURHOOD` vehicles each planned
    once (64 vehicles: 8; 128: 16; 256: 32). A neighbourhood is drawn round one vehicle in collision, so
    with more of them than that the repair cannot take each out once with its neighbourhood. A decision
    from counts known before the search, not a proof (a neighbourhood may hold several; the repair has
    removed every collision only on grids of 16-20 vehicles, none at 64 or more: docs/planner.md); set
    from the repair's own constants, not watching a layout."""
    return (LNS_PLANNINGS_PER_VEHICLE * n_vehicles) // NEIGHBOURHOOD


def unplanned_track(problem: SwarmProblem, agent: int, options: PriorityOptions) -> GridTrack:
    """What the occupancy holds for a vehicle not planned yet: its reserved start or its prediction."""
    if options.reserve_starts:
        return reserved_track(problem, agent)
    return predicted_track(problem, agent, hold_s=options.hold_s)


def prioritized_tracks(
    problem: SwarmProblem,
    order: list[int],
    options: PriorityOptions,
    *,
    horizon_steps: int,
    initial: dict[int, GridTrack] | None = None,
    progress: Callable[[str, float], None] | None = None,
    deadline: float | None = None,
) -> PriorityResult:
    """Tracks of every agent of ``order`` (see module); :class:`PrioritizedFailed` when a vehicle
    still cannot be planned once ``options.max_repairs`` repairs are spent. ``initial``: tracks in
    place before the first vehicle of ``order`` is planned (as if planned first; repairs may take
    them out and plan them again), e.g. straight lines that conflict with nobody."""
    return _in_order(
        problem,
        order,
        options,
        horizon_steps=horizon_steps,
        initial=initial or {},
        progress=progress,
        deadline=deadline,
    )


def _in_order(
    problem: SwarmProblem,
    order: list[int],
    options: PriorityOptions,
    *,
    horizon_steps: int,
    initial: dict[int, GridTrack],
    progress: Callable[[str, float], None] | None,
    deadline: float | None,
) -> PriorityResult:
    """One pass in ``order`` with repairs (see module)."""
    occ = Occupancy(problem, [], horizon_steps)
    planned: dict[int, GridTrack] = {}
    order = [a for a in initial if a not in order] + list(order)
    rank = {a: i for i, a in enumerate([*initial, *(a for a in order if a not in initial)])}
    after: dict[int, set[int]] = {a: set() for a in order}  # a -> vehicles a goes before (repairs)
    for a in order:
        if problem.pinned[a]:
            planned[a] = GridTrack(a, int(problem.type_index[a]), problem.starts_m[a].copy(), [])
            occ.put(planned[a])
        elif a in initial:
            planned[a] = initial[a]
            occ.put(initial[a])
        else:
            occ.put(unplanned_track(problem, a, options))
    queue = deque(a for a in order if not problem.pinned[a] and a not in initial)
    result = PriorityResult(planned, 0, 0)
    reversed_for: set[tuple[int, frozenset[int]]] = set()  # repairs against the order made so far
    stuck: list[int] = []  # vehicles left on their ideal tracks, in collision (removed at the end)
    total = len(queue)
    res = Reservations(problem, horizon_steps, options.hold_s) if options.reserve_starts else None
    while queue:
        a = queue.popleft()
        if deadline is not None and time.perf_counter() > deadline:
            raise PlanNotFound(
                "no plan found within the time budget (prioritised planning)", details={"nodes": result.planned}
            )
        if progress is not None and result.planned % 8 == 0:
            done = len(planned) - int(problem.pinned.sum())
            progress(f"continuous planning {done}/{total} ({result.repairs} repairs)", 0.1 + 0.5 * done / max(1, total))
        if options.max_plannings is not None and result.planned >= options.max_plannings:
            result.history.append(f"{problem.names[a]}: planning budget of {options.max_plannings} spent")
            raise PrioritizedFailed(a, result.repairs, result.history, planned=result.planned)
        # each queued vehicle needs a planning of its own before the queue empties, and the check above
        # stops the pass once the budget is spent: it cannot end before then (exact)
        if options.give_up_early and options.max_plannings is not None:
            if result.planned + 1 + len(queue) > options.max_plannings:
                result.history.append(
                    f"{problem.names[a]}: planning budget of {options.max_plannings} cannot plan the "
                    f"{1 + len(queue)} vehicle(s) left (given up early)"
                )
                raise PrioritizedFailed(
                    a, result.repairs, result.history, planned=result.planned, charged=options.max_plannings
                )
        prediction = occ.remove(a)
        track = _plan(occ, a, options)
        result.planned += 1
        if track is not None:
            planned[a] = track
            occ.put(track)
            continue
        ideal = ideal_track(problem, occ, a)
        in_conflict = occ.conflicting_agents(ideal) if ideal is not None else set()
        guesses = [b for b in in_conflict if b not in planned and b in occ.tracks]
        if res is not None and guesses:  # release the reserved starts in its way: they leave
            res.release(occ, guesses)
            track = _plan(occ, a, options)
            result.planned += 1
            if track is not None:
                result.history.append(f"{problem.names[a]} released the starts of " + _names(problem, guesses))
                planned[a] = track
                occ.put(track)
                res.plan_next(a, guesses, occ, queue)
                continue
            res.reserve(occ, guesses)
        if guesses:  # predictions are assumptions: drop those in its way and plan it again
            result.history.append(
                f"{problem.names[a]} past the predictions of " + ", ".join(problem.names[b] for b in sorted(guesses))
            )
            dropped = [occ.remove(b) for b in guesses]
            track = _plan(occ, a, options)
            result.planned += 1
            for old in dropped:
                if old is not None:
                    occ.put(old)
            if track is not None:
                planned[a] = track
                occ.put(track)
                if res is not None:
                    res.plan_next(a, guesses, occ, queue)
                continue
        in_way = sorted((b for b in in_conflict if b in planned and not problem.pinned[b]), key=lambda b: rank[b])
        if ideal is not None and not any(b in planned for b in in_conflict):  # only predictions in its way
            planned[a] = ideal
            occ.put(ideal)
            result.history.append(f"{problem.names[a]} on its ideal track (only predictions in its way)")
            if res is not None:
                res.plan_next(a, guesses, occ, queue)
            continue
        blockers = [b for b in in_way if a not in after[b]]
        why = None
        if not in_way or result.repairs >= options.max_repairs:
            why = "nobody to take out" if not in_way else f"repair budget of {options.max_repairs} spent"
        elif not blockers and (a, frozenset(in_way)) in reversed_for:  # the same reversal again
            why = "goes round in a circle with " + ", ".join(problem.names[b] for b in in_way)
        if why is not None and options.holding:  # wait aside at a holding point for those in its way (swarm.holding)
            track = _via_holding(occ, a, options, planned, res, queue, result)
            if track is not None:
                result.history.append(f"{problem.names[a]}: {why}; via a holding point instead")
                planned[a] = track
                occ.put(track)
                continue
        if why is not None:
            result.history.append(f"{problem.names[a]}: {why}")
            if options.collisions and ideal is not None:  # in collision with those in its way (swarm.lns)
                track = plan_ignoring(occ, a, set(in_way), options.through, heights=options.heights)
                result.planned += 1
                planned[a] = ideal if track is None else track
                occ.put(planned[a])
                stuck.append(a)
                if options.max_in_collision is not None and len(stuck) > options.max_in_collision:
                    raise _too_many_in_collision(problem, stuck, queue, options, result)
                continue
            if prediction is not None:
                occ.put(prediction)
            raise PrioritizedFailed(a, result.repairs, result.history, planned=result.planned)
        result.repairs += 1
        against = not blockers
        if against:  # every vehicle in its way goes before it: reverse that for these pairs
            blockers = in_way
            result.against_order += 1
            reversed_for.add((a, frozenset(blockers)))
        result.history.append(
            f"{problem.names[a]} before "
            + ", ".join(problem.names[b] for b in blockers)
            + (" (against the order)" if against else "")
        )
        for b in blockers:  # a goes before b from now on, and before everything b goes before
            after[b].discard(a)
            after[a] |= {b} | (after[b] - {a})
        for c in after:
            if a in after[c]:
                after[c] |= after[a] - {c}
        for b in blockers:
            del planned[b]
            occ.put(unplanned_track(problem, b, options))
        queue.extendleft(reversed([a, *blockers]))
    result.released = 0 if res is None else res.released
    if stuck:
        _remove_collisions(occ, planned, stuck, options, result, deadline, res)
    return result


def _plan(occ: Occupancy, a: int, options: PriorityOptions) -> GridTrack | None:
    """``a`` planned against ``occ`` (:func:`~proxplan.planner.swarm.single.plan_one`), and with
    ``options.raised`` also along its raised routes (:func:`~proxplan.planner.swarm.raised.raised_or`: the
    earlier arrival kept)."""
    track = plan_one(occ, a, options.through, heights=options.heights)
    return raised_or(occ, a, options.through, track) if options.raised else track


def _via_holding(
    occ: Occupancy,
    a: int,
    options: PriorityOptions,
    planned: dict[int, GridTrack],
    res: Reservations | None,
    queue: deque,
    result: PriorityResult,
) -> GridTrack | None:
    """``a`` through a holding point (:func:`~proxplan.planner.swarm.holding.plan_via_holding`), or None;
    with reserved starts, where none can be timed, once more through each holding point with the reserved
    starts in the way of its chain released (as for the ideal track: they are planned next). One planning
    per attempt (each times at most ``MAX_HOLDING_POINTS`` chains)."""
    problem = occ.problem
    track = plan_via_holding(occ, a, options.through)
    result.planned += 1
    if track is None and res is not None:
        held = {b for b in occ.tracks if b not in planned and b != a}
        result.planned += 1
        for h in holding_points(occ, a):
            guesses = res.along(a, held_in_way(occ, a, h, held))
            if not guesses:
                continue
            res.release(occ, guesses)
            got = time_chain(occ, a, np.array([problem.starts_m[a], h, problem.goals_m[a]]), through=options.through)
            if got is not None:
                track = got.track
                res.plan_next(a, guesses, occ, queue)
                result.history.append(f"{problem.names[a]} released the starts of {_names(problem, guesses)} to hold")
                break
            res.reserve(occ, guesses)
    if track is not None:
        result.held += 1
    return track


def _too_many_in_collision(
    problem: SwarmProblem, stuck: list[int], queue: deque, options: PriorityOptions, result: PriorityResult
) -> PrioritizedFailed:
    """The pass given up on ``PriorityOptions.max_in_collision`` (see there for what it is charged)."""
    ahead = result.planned + len(queue)  # each vehicle still queued needs one planning at least
    repair = LNS_PLANNINGS_PER_VEHICLE * problem.n_agents
    if options.max_plannings is not None:
        repair = max(0, min(repair, options.max_plannings - ahead))
    charged = ahead + repair
    if options.max_plannings is not None:
        charged = max(result.planned, min(charged, options.max_plannings))
    result.history.append(
        f"{len(stuck)} vehicles in collision, more than the {options.max_in_collision} the collision repair "
        f"has neighbourhoods for (given up early, {len(queue)} vehicle(s) still queued)"
    )
    return PrioritizedFailed(stuck[-1], result.repairs, result.history, planned=result.planned, charged=charged)


def _names(problem: SwarmProblem, agents: Iterable[int]) -> str:
    return ", ".join(problem.names[b] for b in sorted(agents))


def _remove_collisions(
    occ: Occupancy,
    planned: dict[int, GridTrack],
    stuck: list[int],
    options: PriorityOptions,
    result: PriorityResult,
    deadline: float | None,
    res: Reservations | None = None,
) -> None:
    """The collisions of the vehicles left on their ideal tracks removed (:mod:`proxplan.planner.swarm.lns`),
    within what is left of the pass's plannings; :class:`PrioritizedFailed` when some are left."""
    problem = occ.problem
    left = LNS_PLANNINGS_PER_VEHICLE * problem.n_agents
    if options.max_plannings is not None:
        left = min(left, options.max_plannings - result.planned)
    early: list[str] = []
    plannings, tried, pairs = remove_collisions(
        occ,
        planned,
        stuck,
        plan_one=lambda o, b: _plan(o, b, options),
        plan_ignoring=lambda o, b, others: (
            plan_ignoring(o, b, others, options.through, heights=options.heights)
            or ideal_track(problem, o, b)
            or planned[b]
        ),
        # with reserved starts, a neighbourhood is planned under the pass's own scheme: its vehicles not
        # planned again yet hold their starts, released for one that cannot be planned around them
        predicted=(
            (lambda b: predicted_track(problem, b, hold_s=options.hold_s))
            if res is None
            else (lambda b: reserved_track(problem, b))
        ),
        release=None if res is None else res.release_in_way,
        reserve=None if res is None else res.reserve,
        extra_neighbours=lambda b: start_visitors(occ, b),
        budget=max(0, left),
        seed=options.seed,
        deadline=deadline,
        early=early,
    )
    result.planned += plannings
    result.collision_repairs += tried
    result.history.append(
        f"{len(stuck)} vehicle(s) on ideal tracks in collision: {tried} neighbourhoods, {pairs} pairs left"
        + "".join(f" ({why})" for why in early)
    )
    if pairs:
        # given up early, the repair is charged the plannings it would have spent (at least its budget)
        charged = result.planned + (max(0, left) - plannings if early else 0)
        raise PrioritizedFailed(stuck[-1], result.repairs, result.history, planned=result.planned, charged=charged)


# PriorityOptions, PriorityResult, PrioritizedFailed, dependency_order and single's planners re-exported: their
# import path from this module kept
__all__ = [
    "PrioritizedFailed",
    "PriorityOptions",
    "PriorityResult",
    "dependency_order",
    "ideal_track",
    "in_collision_cap",
    "plan_one",
    "prioritized_tracks",
]
