"""Repair of the vehicles left in collision by prioritised planning (MAPF-LNS2, Li et al. AAAI 2022).

When a pass of :mod:`proxplan.planner.swarm.priority` cannot plan a vehicle within its repairs, the
vehicle is planned against every track but those of the vehicles in its way (so it may collide with
those only; its *ideal track*, the track it would fly alone, when even that fails), and the pass
goes on: every vehicle planned after it plans around it as around any other track. What is left is a complete set of tracks in which only known pairs collide
(:meth:`~proxplan.planner.swarm.occupancy.Occupancy.conflicting_agents`, the queries' own test).

Large neighbourhood search then removes those collisions, a neighbourhood at a time: one vehicle
in collision (drawn with the pass's seeded generator), the vehicles it collides with and those that
come to its start (it could not leave before them), at most :data:`NEIGHBOURHOOD` of them, are taken
out and planned again, one after another in a random order, against everyone else (the vehicles of
the neighbourhood not planned yet are predictions, as in the pass; with reserved starts,
:mod:`proxplan.planner.swarm.reserve`, they hold their starts, and a vehicle that cannot be planned
around those in the way of its ideal track releases them (``release``): planned once more, and if
that succeeds they are planned next, as in the pass). A vehicle that still cannot be planned flies
in collision with its neighbourhood only (its ideal track if even that fails). The new tracks are kept when the count of colliding pairs did
not grow (LNS2's acceptance), else the old ones come back. It ends when no pair collides (the tracks
are then conflict-free: each was planned against every track in place, or its collisions counted),
or gives up when its count of single-vehicle plannings is spent: a count, so the same seed gives
the same plan on every machine. It gives up early, before the count is spent, once the count left
cannot remove the collisions (:func:`plannings_needed`, :data:`HOOD_PLANNINGS`): it would give up
all the same, later.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable

import numpy as np

from proxplan.planner.errors import PlanNotFound
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.tracks import GridTrack

# vehicles planned again together at most: the largest neighbourhoods LNS2 uses (Li et al. 2022, 4-32
# agents, their adaptive choice); 8 is the most that one repair of the pass takes out on the named
# layouts at 64 vehicles (docs/planner.md), so a neighbourhood holds one repair's vehicles
NEIGHBOURHOOD = 8
# single-vehicle plannings one neighbourhood can make at most: each of its vehicles is planned, once
# more after it released reserved starts in its way, and once more in collision (remove_collisions)
HOOD_PLANNINGS = 3 * NEIGHBOURHOOD


def plannings_needed(pairs) -> int:
    """A lower bound on the single-vehicle plannings that remove every colliding pair of ``pairs``
    ((i, j) tuples): a pair collides until one of its two vehicles is planned again, so the vehicles
    planned again cover every pair, and pairs with no vehicle in common (a matching, here a greedy
    maximal one over the sorted pairs) need one planning each. Counts only, so the decision it
    supports is the same on every machine."""
    used: set[int] = set()
    count = 0
    for a, b in sorted(pairs):
        if a not in used and b not in used:
            used.update((a, b))
            count += 1
    return count


def colliding_pairs(occ: Occupancy, agents) -> set[tuple[int, int]]:
    """The pairs (i < j) of tracks in ``occ`` that collide, of which one is in ``agents``."""
    pairs: set[tuple[int, int]] = set()
    for a in agents:
        for b in occ.conflicting_agents(occ.tracks[a]):
            if not occ.tracks[b].vanishes:
                pairs.add((min(a, b), max(a, b)))
    return pairs


def remove_collisions(
    occ: Occupancy,
    planned: dict[int, GridTrack],
    in_collision: list[int],
    *,
    plan_one: Callable[[Occupancy, int], GridTrack | None],
    plan_ignoring: Callable[[Occupancy, int, set[int]], GridTrack],
    predicted: Callable[[int], GridTrack],
    extra_neighbours: Callable[[int], set[int]],
    budget: int,
    release: Callable[[Occupancy, int, list[int]], list[int]] | None = None,
    reserve: Callable[[Occupancy, list[int]], None] | None = None,
    seed: int,
    deadline: float | None = None,
    early: list[str] | None = None,
) -> tuple[int, int, int]:
    """Remove the collisions of the vehicles ``in_collision`` (see module), ``planned`` and ``occ``
    changed in place. Returns (plannings, neighbourhoods tried, colliding pairs left): pairs left > 0
    only when the ``budget`` of plannings was spent, or could not suffice: a neighbourhood starts only
    while fewer than ``budget`` plannings are made and makes at most :data:`HOOD_PLANNINGS`, so once
    :func:`plannings_needed` exceeds ``budget`` - plannings - 1 + ``HOOD_PLANNINGS`` the pairs cannot
    all go (given up early, the reason appended to ``early``)."""
    problem = occ.problem
    rng = np.random.default_rng(seed)
    pairs = colliding_pairs(occ, in_collision)
    plannings = tried = 0
    while pairs and plannings < budget:
        needed = plannings_needed(pairs)
        if needed > budget - plannings - 1 + HOOD_PLANNINGS:
            if early is not None:
                early.append(
                    f"given up early: {len(pairs)} colliding pairs need at least {needed} plannings "
                    f"(disjoint pairs), {budget - plannings} left"
                )
            break
        if deadline is not None and time.perf_counter() > deadline:
            raise PlanNotFound("no plan found within the time budget (collision repair)", details={"nodes": plannings})
        tried += 1
        involved = sorted({a for p in pairs for a in p if not problem.pinned[a]})
        if not involved:
            break
        a = int(involved[rng.integers(len(involved))])
        partners = sorted({b for p in pairs if a in p for b in p} - {a})
        visitors = sorted(extra_neighbours(a) - {a} - set(partners))
        hood = [a, *(b for b in [*partners, *visitors] if b in planned and not problem.pinned[b])]
        hood = list(dict.fromkeys(hood))[:NEIGHBOURHOOD]
        old = {b: planned[b] for b in hood}
        before = {p for p in pairs if p[0] in old or p[1] in old}
        for b in hood:
            occ.put(predicted(b))
        pending = deque(hood[i] for i in rng.permutation(len(hood)))
        while pending:
            b = pending.popleft()
            occ.remove(b)
            track = plan_one(occ, b)
            plannings += 1
            if track is None and release is not None and reserve is not None:
                first = release(occ, b, list(pending))
                if first:
                    track = plan_one(occ, b)
                    plannings += 1
                    if track is None:
                        reserve(occ, first)
                    else:
                        for c in first:
                            pending.remove(c)
                        pending.extendleft(reversed(first))
            if track is None:  # in collision with its neighbourhood only, if it can
                plannings += 1
                track = plan_ignoring(occ, b, set(hood))
            planned[b] = track
            occ.put(track)
        after = colliding_pairs(occ, hood)
        if len(after) <= len(before):
            pairs = (pairs - before) | after
        else:  # LNS2's acceptance: never more colliding pairs
            for b, tr in old.items():
                planned[b] = tr
                occ.put(tr)
    return plannings, tried, len(pairs)


__all__ = ["HOOD_PLANNINGS", "NEIGHBOURHOOD", "colliding_pairs", "plannings_needed", "remove_collisions"]
