"""Earliest-arrival search with waits over a small roadmap of straight rest-to-rest motions.

Nodes are a handful of points (start, goal, lane-change corners, obstacle detours, dodge points
beside the straight line), m; every pair of nodes is an edge flown as one jerk-limited rest-to-rest
Ruckig segment (a straight line, :func:`proxplan.planner.timing.ruckig_segment`), so the timed trajectory is
exactly what :func:`proxplan.planner.timing.time_parameterize` flies later. A vehicle may wait at a node
(while holding there stays valid) before it departs. The search is A* on arrival time (heuristic:
unobstructed minimum time to the goal) where an edge departs at the first time, on a grid of
``step_s``, at which the whole motion is valid against all planned vehicles (one vectorised
:class:`proxplan.planner.checks.validity.BatchChecker` call per candidate departure). This is a small
safe-interval-style planner: waiting replaces the RRT's random search for most vehicles of a
formation change; the RRT remains the fallback.
"""

from __future__ import annotations

import heapq
import math

import numpy as np

from proxplan.physics import KinematicLimits
from proxplan.planner.checks.validity import BatchChecker
from proxplan.planner.timing.durations import DurationTable
from proxplan.planner.timing.segments import ruckig_segment


class _Edge:
    """Samples of one rest-to-rest straight motion: relative times (M,), s, and positions (M, 3), m."""

    def __init__(self, p0: np.ndarray, p1: np.ndarray, limits: KinematicLimits, dt_s: float):
        if float(np.linalg.norm(p1 - p0)) <= 0.0:  # start at the goal: no motion, arrival at departure
            self.duration_s = 0.0
            self.t = np.zeros(1)
            self.p = np.asarray(p0, dtype=float)[None].copy()
            return
        traj = ruckig_segment(p0, p1, limits)
        self.duration_s = float(traj.duration)
        self.t = np.append(np.arange(dt_s, self.duration_s, dt_s), self.duration_s)
        self.p = np.array([traj.at_time(float(t))[0] for t in self.t])


def detour_paths(start: np.ndarray, end: np.ndarray, boxes, *, clearance_m: float) -> list[np.ndarray]:
    """Candidate geometric paths (K, 3), m, from ``start`` to ``end``: the straight line, lane
    changes at either end (fly level at the start's height, change height at the goal, or the
    other way round), and for every inflated obstacle box of ``boxes`` ((min xyz, max xyz), m) the
    straight line passes through, a rectangular bypass on either side of it (two via points
    ``clearance_m`` outside the box's horizontal half-diagonal) and a one-via bypass."""
    paths = [np.array([start, end])]
    if abs(end[2] - start[2]) > 0.05:
        paths.append(np.array([start, [end[0], end[1], start[2]], end]))
        paths.append(np.array([start, [start[0], start[1], end[2]], end]))
        paths.append(np.array([start, [end[0], start[1], start[2]], end]))
        paths.append(np.array([start, [start[0], end[1], end[2]], end]))
    d = end[:2] - start[:2]
    length = float(np.linalg.norm(d))
    if length < 1e-6 or not boxes:
        return paths
    u = d / length
    n = np.array([-u[1], u[0]])
    f = np.linspace(0.0, 1.0, max(2, int(math.ceil(float(np.linalg.norm(end - start)) / 0.02))))
    pts = start + f[:, None] * (end - start)
    for b in boxes:
        lo, hi = np.array(b[:3]), np.array(b[3:])
        if not np.all((pts >= lo) & (pts <= hi), axis=1).any():
            continue
        c = 0.5 * (lo[:2] + hi[:2])
        half = 0.5 * float(np.linalg.norm(hi[:2] - lo[:2])) + clearance_m
        along = float(np.dot(c - start[:2], u))
        lateral = float(np.dot(c - start[:2], n))

        def via(s_m: float, lat_m: float) -> np.ndarray:
            s_m = min(max(s_m, 0.0), length)
            xy = start[:2] + u * s_m + n * lat_m
            return np.array([xy[0], xy[1], start[2] + (end[2] - start[2]) * s_m / length])

        for side in (1.0, -1.0):
            lat = lateral + side * half
            paths.append(np.array([start, via(along - half, lat), via(along + half, lat), end]))
            paths.append(np.array([start, via(along, lateral + side * 2.0 * half), end]))
    return paths


def roadmap_nodes(start: np.ndarray, end: np.ndarray, boxes, *, dodge_m: float, clearance_m: float) -> list[np.ndarray]:
    """Nodes of the waiting search, m: the start (node 0, even where it is the goal: a vehicle that
    stays put), the via points of :func:`detour_paths`, axis-aligned corners, dodge points
    ``dodge_m`` beside and above/below the start and the goal, and the goal (last); duplicates
    removed."""
    pts = [start]
    for path in detour_paths(start, end, boxes, clearance_m=clearance_m):
        pts.extend(path[1:-1])
    for z in (start[2], end[2]):  # axis-aligned corners (corridors, junctions)
        pts.extend([np.array([start[0], end[1], z]), np.array([end[0], start[1], z])])
    d = end[:2] - start[:2]
    n = np.array([-d[1], d[0], 0.0]) / max(float(np.linalg.norm(d)), 1e-9)
    zhat = np.array([0.0, 0.0, 1.0])
    for anchor in (start, end):
        for v in (n, -n, zhat, -zhat):
            pts.append(anchor + dodge_m * v)
    pts.append(end)
    out: list[np.ndarray] = []
    for p in pts:
        p = np.asarray(p, dtype=float)
        if all(float(np.linalg.norm(p - q)) > 1e-6 for q in out) or p is pts[-1]:
            out.append(p)
    return [q for k, q in enumerate(out) if k in (0, len(out) - 1) or float(np.linalg.norm(q - end)) > 1e-6]


def roadmap_search(
    batch: BatchChecker,
    limits: KinematicLimits,
    durations: DurationTable,
    nodes: list[np.ndarray],
    *,
    hold_from_s: float,
    horizon_s: float,
    step_s: float = 0.1,
    hold_step_s: float = 0.05,
    max_wait_s: float = 8.0,
) -> tuple[np.ndarray, np.ndarray] | None:
    """Waypoints (K, 3), m, and times (K,), s, from ``nodes[0]`` (at t = 0) to ``nodes[-1]``
    arriving at or after ``hold_from_s`` (from then on holding the goal is valid), or None.

    Repeated waypoints in the result are waits."""
    pts = [np.asarray(p, dtype=float) for p in nodes]
    goal = len(pts) - 1
    dt_c = min(0.05, 0.04 / limits.max_speed_mps)
    h = [durations.duration_s(float(np.linalg.norm(pts[goal] - p))) for p in pts]
    edges: dict[tuple[int, int], _Edge | None] = {}

    def edge(i: int, j: int) -> _Edge | None:
        if (i, j) not in edges:
            e = _Edge(pts[i], pts[j], limits, dt_c)
            static, _ = batch.conflict_codes(e.p, np.full(e.t.size, -1.0))
            edges[(i, j)] = None if (static >= 0).any() else e
        return edges[(i, j)]

    best_t = {0: 0.0}
    parent: dict[int, tuple[int, float]] = {}  # node -> (previous node, departure time)
    heap = [(h[0], 0.0, 0)]
    done: set[int] = set()
    while heap:
        _, t, i = heapq.heappop(heap)
        if i in done:
            continue
        done.add(i)
        if i == goal:
            return _unwind(pts, parent, best_t, goal)
        # how long node i can be held from t (waits are bounded by max_wait_s)
        tw = t + hold_step_s * np.arange(int(max_wait_s / hold_step_s) + 1)
        first, _ = batch.first_conflict(np.repeat(pts[i][None], tw.size, 0), tw)
        hold_end = t + max_wait_s if first < 0 else float(tw[max(0, first - 1)])
        if first == 0:
            continue
        goal_best = best_t.get(goal, math.inf)
        for j in range(len(pts)):
            if j == i or j in done:
                continue
            e = edge(i, j)
            if e is None:
                continue
            first_dep = t
            if j == goal and hold_from_s - e.duration_s > t:
                first_dep = t + step_s * math.ceil((hold_from_s - e.duration_s - t) / step_s - 1e-9)
            last_dep = min(hold_end, goal_best - h[j] - e.duration_s - 1e-9, horizon_s - e.duration_s)
            if last_dep < first_dep - 1e-9:
                continue
            deps = first_dep + step_s * np.arange(int((last_dep - first_dep) / step_s + 1e-9) + 1)
            dep = _first_valid_departure(batch, e, deps)
            if dep is None:
                continue
            arr = dep + e.duration_s
            if arr < best_t.get(j, math.inf):
                best_t[j] = arr
                parent[j] = (i, dep)
                heapq.heappush(heap, (arr + h[j], arr, j))
                if j == goal:
                    goal_best = arr
    return None


def _first_valid_departure(batch: BatchChecker, e: _Edge, deps: np.ndarray, chunk: int = 24) -> float | None:
    """The first departure time (s) in ``deps`` at which the edge's motion is valid; several
    departures are checked in one vectorised call."""
    m = e.t.size
    for a in range(0, deps.size, chunk):
        d = deps[a : a + chunk]
        xyz = np.tile(e.p, (d.size, 1))
        t = (d[:, None] + e.t[None, :]).ravel()
        _, code = batch.conflict_codes(xyz, t)
        ok = ~(code >= 0).reshape(d.size, m).any(axis=1)
        if ok.any():
            return float(d[int(np.argmax(ok))])
    return None


def _unwind(pts, parent, best_t, goal) -> tuple[np.ndarray, np.ndarray]:
    way: list[np.ndarray] = [pts[goal]]
    times: list[float] = [best_t[goal]]
    j = goal
    while j in parent:
        i, dep = parent[j]
        if dep > best_t[i] + 1e-9:  # wait at i from its arrival until departure
            way.append(pts[i])
            times.append(dep)
        way.append(pts[i])
        times.append(best_t[i])
        j = i
    return np.array(way[::-1]), np.array(times[::-1])
