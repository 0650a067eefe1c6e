"""Two-way traffic in lanes: each vehicle flies a lane route kept to the right of its own heading, timed one
after another in a flow order (issue 37; the routes and the timing measured in round 23B as
``benchmarks/why_128.py --flow``, a stage of the stacked plan's levels since round 27A).

World frame, z up, m; times on the swarm grid (``GRID_DT_S``).

* **Lane routes** (:func:`lane_routes`): start -> start + D -> goal + D -> goal, the middle leg round the
  obstacles by the wavefront in empty space where its straight line is not free. D is an offset of
  ``FLOW_LATERAL_REACHES`` x the widest keep-out's horizontal reach (``SwarmProblem.reach_xy_m``) to the
  right of the vehicle's heading (start -> goal; ``KEEP_RIGHT``), and ``FLOW_DZ_M`` up or down where the
  free box allows (or none). So vehicles crossing the same passage in opposite directions are offset to
  opposite sides - derived from each route's own direction, never from a layout - and a route may pass
  over or under rows of parked vehicles that wall one height. Of the offsets whose flight alone comes
  within keep-out of the fewest other starts and goals, the least taken so far (lanes spread).
* **Flow timing** (:func:`flow_timing`): a vehicle after those whose starts its route passes and before
  those whose goals it passes (cycles broken by the fewest unmet, ties the longest flight first); each
  timed exactly through its waypoints (:func:`~proxplan.planner.swarm.chain.time_chain`) against those
  timed before it, the others' starts reserved until they are timed (a vehicle releases the reserved starts
  within keep-out of its goal and those its lane route passes, and they are timed next; where its lane route cannot be
  timed, :func:`~proxplan.planner.swarm.single.plan_one` stopping at its waypoints). A vehicle whose start is within
  keep-out of another's goal is timed before that one where no cycle forbids it (``ORDER_BY_ENDS``). Where a vehicle cannot be timed, everything
  again with it first, at most ``FLOW_RESTARTS`` times (a count: the same problem gives the same plan), and
  never an order timed before (the timing is a function of the order: it would fail the same way).
  Every track is conflict-free against those timed before it, so the whole plan is.
* **The stage** (:func:`lanes_stage`): the flow timing on a horizon of ``LANES_HORIZON_FACTOR`` x the
  bound; the stacked plan's levels ask it where prioritised planning gave up (round 27A).
"""

from __future__ import annotations

import time
from collections import Counter

import numpy as np

from proxplan.planner.swarm.chain import time_chain
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.problem import SwarmProblem
from proxplan.planner.swarm.reserve import reserved_track
from proxplan.planner.swarm.single import plan_one
from proxplan.planner.swarm.stage import Stage
from proxplan.planner.swarm.tracks import GRID_DT_S, GridTrack
from proxplan.planner.swarm.wave import wave_route
from proxplan.planner.ties import TIME_RESOLUTION_S, tie_key
from proxplan.planner.timing.profile import LineMove, rest_to_rest

# two headings are one direction group when their cosine exceeds this (within 60 degrees; why_128 --flow)
FLOW_GROUP_COS = 0.5
# a lane route's middle leg is offset by these multiples of the widest keep-out's horizontal reach
# (SwarmProblem.reach_xy_m) sideways, and by these heights, m (round 23B, set on corridor-64 and pillar-64:
# 0.5 m is where a Crazyflie's keep-out over another narrows to 0.09-0.26 m, under the rows' 0.30 m half pitch)
FLOW_LATERAL_REACHES = (0.75, 1.0)
FLOW_DZ_M = (0.0, 0.5, -0.5)
# the sides a lane route may be offset to, +1 right of its heading, -1 left: right only keeps opposite
# streams on opposite sides (the stage); both spread the lanes (why_128 --flow's default)
KEEP_RIGHT = (1.0,)
BOTH_SIDES = (1.0, -1.0)
# the flow timing starts again at most this many times, the vehicle it could not time first (round 23B)
FLOW_RESTARTS = 32
# a vehicle about to be timed releases the reserved starts its lane route passes as well as those at its goal,
# and they are timed next (corridor-128's Crazyflie level alone: 6.63x, 108.7 s CPU -> 6.12x, 43.9 s; round 27A)
RELEASE_ON_ROUTE = True
# the flow order also puts b before a where b's start is within keep-out of a's goal (b leaves before a
# arrives), not only by the starts and goals a's route passes. Round 28A, corridor-128's Crazyflie level
# alone: a lane route failed where a vehicle timed before it sat at its goal by the route's start (50
# plan_one fallbacks, 4 restarts -> 26 fallbacks, 0 restarts)
ORDER_BY_ENDS = True
# a lane route that cannot be timed falls back on plan_one stopping at its route's waypoints (False) or
# flying through them (True): through, its timing of a wavefront route of many waypoints was ~1 s a
# fallback (round 28A, same level: the stage 37.3 -> 10.1 s CPU with both changes, 6.12x -> 6.23x before
# re-timing, which flies through the waypoints afterwards)
FALLBACK_THROUGH = False
# the stage's horizon: this many times the level's straight-line bound (a count of grid steps). The plan it
# replaces where it runs, the lattice plan in lock-step, was 7.4-17.2x at 128 (pillar, corridor: round 26B)
LANES_HORIZON_FACTOR = 12.0

__all__ = [
    "BOTH_SIDES",
    "FLOW_DZ_M",
    "FLOW_LATERAL_REACHES",
    "FLOW_RESTARTS",
    "KEEP_RIGHT",
    "LANES_HORIZON_FACTOR",
    "direction_groups",
    "flow_order",
    "flow_timing",
    "lane_routes",
    "lanes_stage",
]


def direction_groups(problem: SwarmProblem) -> list[tuple[np.ndarray, list[int]]]:
    """Vehicles grouped by horizontal heading (start -> goal): each joins the first group whose mean heading
    is within ``FLOW_GROUP_COS`` of its own (in index order); (mean unit heading, members) per group."""
    d = (problem.goals_m - problem.starts_m)[:, :2]
    u = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-9)
    groups: list[list] = []
    for a in range(problem.n_agents):
        for grp in groups:
            if float(grp[0] @ u[a]) / max(float(np.linalg.norm(grp[0])), 1e-9) > FLOW_GROUP_COS:
                grp[0] = grp[0] + u[a]
                grp[1].append(a)
                break
        else:
            groups.append([u[a].copy(), [a]])
    return [(g[0] / max(float(np.linalg.norm(g[0])), 1e-9), g[1]) for g in groups]


def _footprint(problem: SwarmProblem, a: int, W: np.ndarray) -> GridTrack:
    """``a`` flown along the chain ``W`` alone, rest to rest on each leg (no shortcut: the route itself), a
    GridTrack."""

    moves, k = [], 0
    for p0, p1 in zip(W[:-1], W[1:], strict=True):
        length = float(np.linalg.norm(p1 - p0))
        if length > 1e-9:
            mv = LineMove(p0, p1, rest_to_rest(length, problem.limits[a], GRID_DT_S))
            moves.append((k, mv))
            k += mv.steps
    return GridTrack(a, int(problem.type_index[a]), W[0].copy(), moves)


def lane_routes(problem: SwarmProblem, horizon: int, sides: tuple[float, ...] = BOTH_SIDES) -> tuple[dict, dict]:
    """Per vehicle a lane route start -> start + D -> goal + D -> goal (the middle leg round the obstacles by
    the wavefront in empty space), D one of the offsets FLOW_LATERAL_REACHES x FLOW_DZ_M (and none) to the
    right or left of its heading (``sides``: +1 right, -1 left) and up or down. Of the offsets whose flight
    alone along the route comes within keep-out of the fewest other starts and goals (those within keep-out
    of its own start or goal aside: they are timing, not the route), the one taken by the fewest vehicles so
    far (lanes spread over the offsets, the vehicles assigned longest flight first; ties: the earlier
    arrival). Returns (routes, (starts hit, goals hit, arrival s flown rest to rest along the route) per
    vehicle)."""

    A = problem.n_agents
    empty = Occupancy(problem, [], horizon)
    starts = Occupancy(problem, [reserved_track(problem, b) for b in range(A)], horizon)
    goals = Occupancy(
        problem, [GridTrack(b, int(problem.type_index[b]), problem.goals_m[b].copy(), []) for b in range(A)], horizon
    )
    lateral = [0.0] + [sgn * f for f in FLOW_LATERAL_REACHES for sgn in sides]
    candidates: dict[int, list] = {}
    for a in range(A):
        s, g = problem.starts_m[a], problem.goals_m[a]
        ends = [GridTrack(a, int(problem.type_index[a]), q.copy(), []) for q in (s, g)]
        own_s = set().union(*(starts.conflicting_agents(e) for e in ends))
        own_g = set().union(*(goals.conflicting_agents(e) for e in ends))
        d = (g - s)[:2] / max(float(np.linalg.norm((g - s)[:2])), 1e-9)
        right = np.array([d[1], -d[0], 0.0])
        candidates[a] = []
        for dz in FLOW_DZ_M:
            for lat in lateral:
                D = lat * problem.reach_xy_m * right + np.array([0.0, 0.0, dz])
                P, Q = s + D, g + D
                if (lat or dz) and not (
                    problem.static_free(np.array([P, Q])).all()
                    and problem.segment_free(s, P)
                    and problem.segment_free(Q, g)
                ):
                    continue
                M = np.array([P, Q]) if problem.segment_free(P, Q) else wave_route(empty, a, P, Q)
                if M is None:
                    continue
                W = M if not (lat or dz) else np.vstack([s[None], M, g[None]])
                track = _footprint(problem, a, W)
                hs = starts.conflicting_agents(track) - own_s - {a}
                hg = goals.conflicting_agents(track) - own_g - {a}
                candidates[a].append(((lat, dz), len(hs) + len(hg), W, (hs, hg, track.arrival_s)))
        assert candidates[a], f"{problem.names[a]}: no route at all"
    taken: Counter = Counter()
    routes, hits = {}, {}
    for a in sorted(range(A), key=lambda a: (-tie_key(min(c[3][2] for c in candidates[a]), TIME_RESOLUTION_S), a)):
        fewest = min(c[1] for c in candidates[a])
        lane, _, W, hit = min(
            (c for c in candidates[a] if c[1] == fewest),
            key=lambda c: (taken[c[0]], tie_key(c[3][2], TIME_RESOLUTION_S), c[0]),
        )
        taken[lane] += 1
        routes[a], hits[a] = W, hit
    return routes, hits


def flow_order(problem: SwarmProblem, hits: dict, horizon: int) -> tuple[list[int], int]:
    """The flow order of :func:`flow_timing` (``hits`` from :func:`lane_routes`): a vehicle after those whose
    starts its route passes and, with ``ORDER_BY_ENDS``, those whose starts are within keep-out of its goal (they
    leave before it arrives), and before those whose goals its route passes; where none is ready (a cycle), the
    one with the fewest unmet, ties the longest flight first. Returns (order, cycles broken)."""
    A = problem.n_agents
    before = {a: set(hits[a][0]) for a in range(A)}
    for a in range(A):
        for b in hits[a][1]:
            before[b].add(a)
    if ORDER_BY_ENDS:  # b leaves before a arrives where b's start is within keep-out of a's goal
        starts = Occupancy(problem, [reserved_track(problem, b) for b in range(A)], horizon)
        for a in range(A):
            at_goal = GridTrack(a, int(problem.type_index[a]), problem.goals_m[a].copy(), [])
            before[a] |= starts.conflicting_agents(at_goal) - {a}
    order: list[int] = []
    done: set[int] = set()
    broken = 0
    while len(order) < A:
        ready = [a for a in range(A) if a not in done and before[a] <= done]
        if not ready:
            broken += 1
            ready = [min((a for a in range(A) if a not in done), key=lambda a: (len(before[a] - done), -hits[a][2], a))]
        pick = min(ready, key=lambda a: (-hits[a][2], a))
        order.append(pick)
        done.add(pick)
    return order, broken


def flow_timing(problem: SwarmProblem, routes: dict, hits: dict, horizon: int) -> tuple[dict, str]:
    """Every vehicle timed along its lane route (exact safe-interval timing through waypoints against those
    timed before it, the others' starts reserved until timed; a vehicle whose goal is within keep-out of
    reserved starts releases them and they are timed next; a failed timing falls back on plan_one), in the
    flow order: a vehicle after those whose starts its route passes or whose starts are within keep-out of its
    goal (``ORDER_BY_ENDS``) and before those whose goals it passes,
    cycles broken by the fewest unmet, ties the longest flight first; where a vehicle cannot be timed, all
    again with it first, at most ``FLOW_RESTARTS`` times (a count). Returns (tracks, how it ended)."""

    A = problem.n_agents
    order, broken = flow_order(problem, hits, horizon)
    fallbacks = 0
    tried: set[tuple[int, ...]] = set()  # the orders timed: the timing is a function of the order (exact)
    for restart in range(FLOW_RESTARTS + 1):
        if tuple(order) in tried:  # timed before, failed at the same vehicle: no later restart differs
            break
        tried.add(tuple(order))
        occ = Occupancy(problem, [reserved_track(problem, b) for b in range(A)], horizon)
        tracks: dict = {}
        queue = list(order)
        failed: int | None = None
        while queue:
            a = queue.pop(0)
            occ.remove(a)
            at_goal = GridTrack(a, int(problem.type_index[a]), problem.goals_m[a].copy(), [])
            near = occ.conflicting_agents(at_goal) | (set(hits[a][0]) if RELEASE_ON_ROUTE else set())
            partners = [b for b in sorted(near) if b not in tracks and b != a]
            for b in partners:
                occ.remove(b)
            res = time_chain(occ, a, routes[a], through=True)
            track = None if res is None else res.track
            if track is None:
                fallbacks += 1
                track = plan_one(occ, a, FALLBACK_THROUGH)
            if track is None:
                failed = a
                break
            tracks[a] = track
            occ.put(track)
            for b in partners:
                queue.remove(b)
                queue.insert(0, b)
        if failed is None:
            return tracks, f"all timed, {broken} cycles broken, {fallbacks} fallbacks, {restart} restarts"
        order.remove(failed)
        order.insert(0, failed)  # the vehicle that could not be timed goes first
    assert failed is not None
    why = (
        f"{FLOW_RESTARTS} restarts" if len(tried) > FLOW_RESTARTS else f"{len(tried) - 1} restarts (the order repeats)"
    )
    return (
        tracks,
        f"gave up at vehicle {len(tracks)} ({problem.names[failed]}) after {why}, {broken} cycles broken, "
        f"{fallbacks} fallbacks",
    )


def lanes_stage(problem: SwarmProblem, lower_bound_s: float, extra: dict) -> Stage | None:
    """Lane routes kept to the right (``KEEP_RIGHT``) timed in the flow order (see module), or None where the
    flow timing gives up (said in ``extra["lanes"]``)."""
    t0 = time.perf_counter()
    horizon = int(round(LANES_HORIZON_FACTOR * lower_bound_s / GRID_DT_S))
    routes, hits = lane_routes(problem, horizon, KEEP_RIGHT)
    tracks, how = flow_timing(problem, routes, hits, horizon)
    extra["lanes_time_s"] = round(time.perf_counter() - t0, 3)
    if len(tracks) < problem.n_agents:
        extra["lanes"] = f"lane routes kept right: {how}"
        return None
    makespan = max(tr.arrival_s for tr in tracks.values())
    extra["lanes"] = f"lane routes kept right: {how}, {makespan:.2f} s"
    by_agent = [tracks[a] for a in range(problem.n_agents)]

    def chains(a: int) -> list[np.ndarray]:
        return [np.array([problem.starts_m[a], problem.goals_m[a]]), routes[a]]

    return Stage(by_agent, "prioritised", f"two-way lanes kept right, timed in the flow order ({how})", chains)
