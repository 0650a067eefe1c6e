"""Earliest arrival of one vehicle along a chain of waypoints, against the others' tracks.

The vehicle starts at rest at W_0 at t = 0 and must end at rest at W_m and hold it for good. It may
fly straight from any waypoint to any later one (a shortcut) when that line is statically free,
rest-to-rest at its own limits (:func:`proxplan.planner.timing.profile.rest_to_rest`), and may wait
at any waypoint while holding it is clear. This is safe-interval path planning (Phillips and
Likhachev, 2011) on the chain: a state is (waypoint, safe interval of holding it), expanded in
order of arrival time (Dijkstra); a move from (k, I) departs at the earliest grid step in I that
:meth:`Occupancy.forbidden_departures` allows and whose arrival lands in a safe interval of the next
waypoint. Everything is checked against the tracks exactly on the swarm's grid, so the result is
conflict-free against them.
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass

import numpy as np

from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.tracks import GRID_DT_S, Track
from proxplan.planner.timing.profile import LineMove, rest_to_rest

MAX_SHORTCUT = 6  # a move may skip at most this many waypoints (besides the direct move to the end)


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, end) index pairs of the True runs of ``mask``."""
    m = np.concatenate([[False], mask, [False]]).astype(np.int8)
    d = np.diff(m)
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist()))


@dataclass(frozen=True)
class ChainResult:
    track: Track
    arrival_step: int


def time_chain(
    occ: Occupancy,
    agent: int,
    waypoints_m: np.ndarray,
    *,
    leave_start_by: int | None = None,
    arrive_by: int | None = None,
) -> ChainResult | None:
    """The earliest-arrival timing of ``agent`` along ``waypoints_m`` (m+1, 3), or None.

    ``leave_start_by``: the vehicle may not hold its start after this grid step. ``arrive_by``:
    only results arriving no later than this step are of interest (prunes the search)."""
    problem = occ.problem
    W = np.asarray(waypoints_m, dtype=float)
    m = len(W) - 1
    T = occ.horizon
    limits = problem.limits[agent]
    holds = [occ.forbidden_holds(agent, W[k]) for k in range(m + 1)]
    if leave_start_by is not None:
        holds[0][leave_start_by + 1 :] = True
    if holds[0][0]:
        return None
    intervals = [_runs(~h) for h in holds]
    goal_ok = [e >= T for _, e in intervals[m]]
    if not any(goal_ok):
        return None
    moves: dict[tuple[int, int], tuple[LineMove, np.ndarray] | None] = {}

    def move(k: int, j: int):
        if (k, j) not in moves:
            if not problem.segment_free(W[k], W[j]):
                moves[(k, j)] = None
            else:
                dist = float(np.linalg.norm(W[j] - W[k]))
                mv = LineMove(W[k], W[j], rest_to_rest(dist, limits, GRID_DT_S))
                moves[(k, j)] = (mv, occ.forbidden_departures(agent, mv.positions(), mv.profile.arc_m))
        return moves[(k, j)]

    best: dict[tuple[int, int], int] = {(0, 0): 0}
    parent: dict[tuple[int, int], tuple[int, int, int, LineMove]] = {}
    heap = [(0, 0, 0)]
    limit = T if arrive_by is None else min(T, arrive_by + 1)
    while heap:
        t, k, iv = heapq.heappop(heap)
        if best.get((k, iv), T + 1) < t:
            continue
        if k == m and goal_ok[iv]:
            out: list[tuple[int, LineMove]] = []
            node = (k, iv)
            while node in parent:
                pk, piv, dep, mv = parent[node]
                out.append((dep, mv))
                node = (pk, piv)
            track = Track(agent, int(problem.type_index[agent]), W[0].copy(), out[::-1])
            return ChainResult(track, t)
        s_iv, e_iv = intervals[k][iv]
        targets = list(range(k + 1, min(m, k + 1 + MAX_SHORTCUT) + 1))
        if m not in targets:
            targets.append(m)
        for j in targets:
            got = move(k, j)
            if got is None:
                continue
            mv, bad = got
            n = mv.profile.steps
            lo_d, hi_d = t, min(e_iv - 1, limit - 1 - n)
            if hi_d < lo_d:
                continue
            deps = np.flatnonzero(~bad[lo_d : hi_d + 1]) + lo_d
            if deps.size == 0:
                continue
            arrs = deps + n
            ok = ~holds[j][arrs]
            deps, arrs = deps[ok], arrs[ok]
            if deps.size == 0:
                continue
            starts = np.array([a for a, _ in intervals[j]])
            ivs = np.searchsorted(starts, arrs, side="right") - 1
            seen: set[int] = set()
            for d0, a0, i0 in zip(deps.tolist(), arrs.tolist(), ivs.tolist()):
                if i0 in seen:
                    continue
                seen.add(i0)
                if a0 < best.get((j, i0), T + 1):
                    best[(j, i0)] = a0
                    parent[(j, i0)] = (k, iv, d0, mv)
                    heapq.heappush(heap, (a0, j, i0))
    return None
