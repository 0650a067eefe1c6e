"""Continuous-time improvement of a conflict-free swarm plan, one vehicle at a time.

Starting from conflict-free tracks (the lock-step conversion), each pass takes the vehicles in
order of decreasing arrival time and re-plans one at a time against all the others' current tracks
(:func:`proxplan.planner.swarm.chain.time_chain`) along its candidate chains: the straight line to its
goal and its coordination route (:func:`route_chain`). A new track replaces the old one only when it
arrives strictly earlier, and it is conflict-free against every other track, so the plan stays
conflict-free after every replacement and the makespan never grows (a Gauss-Seidel best response).
The number of passes is a count, never a time, so a seed gives the same plan on every machine.

A vehicle whose re-timing gave nothing is not re-timed again until a track that comes within reach
of its chains' box changes (:func:`_near_box`): the answer of its searches depends only on those
tracks, its own track and the horizon, so it would give nothing again (the same plan as re-timing
every vehicle in every pass, tested; issue 37 round 13B: corridor-128's lattice plan had 3 vehicles
replaced in its first pass and none in its second, which re-timed all 128).
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from proxplan.planner.errors import PlanNotFound
from proxplan.planner.swarm.chain import time_chain
from proxplan.planner.swarm.lattice import Lattice
from proxplan.planner.swarm.occupancy import SAMPLING_GROWTH_M, Occupancy
from proxplan.planner.swarm.tracks import GridTrack
from proxplan.planner.timing import CORNER_DEVIATION_M

ROUTE_CORRIDOR_FACTOR = 0.5  # a route shortcut stays within this many lattice spacings of the skipped vertices


def route_vertices(configurations: list[tuple[int, ...]], agent: int) -> tuple[list[int], list[int]]:
    """The agent's vertex route in the coordination plan with waits and loops removed, and the
    indices (in the route) of the vertices where it waited."""
    route: list[int] = []
    waited: set[int] = set()
    for k, q in enumerate(configurations):
        v = q[agent]
        if route and route[-1] == v:
            if k > 0:
                waited.add(v)
            continue
        if v in route:
            route = route[: route.index(v) + 1]
            continue
        route.append(v)
    return route, [i for i, v in enumerate(route) if v in waited]


def route_chain(lattice: Lattice, configurations: list[tuple[int, ...]], agent: int) -> np.ndarray:
    """Waypoints (m+1, 3) of the agent's coordination route, pulled tight: consecutive waypoints
    are joined straight where the skipped vertices lie within ``ROUTE_CORRIDOR_FACTOR`` spacings of
    the line and the line is statically free; vertices where it waited are kept."""
    route, keep = route_vertices(configurations, agent)
    pts = lattice.pos_m[route]
    delta = ROUTE_CORRIDOR_FACTOR * lattice.spacing_m
    out = [0]
    k = 0
    n = len(pts)
    while k < n - 1:
        nxt = [q for q in keep if q > k]
        j = nxt[0] if nxt else n - 1
        while j > k + 1:
            a, b = pts[k], pts[j]
            ab = b - a
            mid = pts[k + 1 : j]
            s = np.clip((mid - a) @ ab / max(float(ab @ ab), 1e-12), 0.0, 1.0)
            if np.linalg.norm(mid - (a + s[:, None] * ab), axis=1).max() <= delta and lattice.problem.segment_free(
                a, b
            ):
                break
            j -= 1
        out.append(j)
        k = j
    return pts[out]


def _box(chains: list[np.ndarray], margin_m: float) -> tuple[np.ndarray, np.ndarray]:
    """The bounding box (lo, hi) of the chains' waypoints grown by ``margin_m``, m: every move the
    search flies lies in it (straight moves between waypoints; through waypoints, the roundings lie
    between chord and corner, within the waypoints' hull)."""
    pts = np.concatenate(chains)
    return pts.min(axis=0) - margin_m, pts.max(axis=0) + margin_m


def _near_box(
    lo: np.ndarray, hi: np.ndarray, box: tuple[np.ndarray, np.ndarray], reach_xy_m: float, reach_z_m: float
) -> bool:
    """Does a track's bounding ``box`` (lo, hi) come within reach (horizontal, vertical, m) of the box
    [lo, hi]? (False: no sample of it can conflict with a vehicle flying inside the box.)"""
    gap = np.maximum(lo - box[1], box[0] - hi)
    return bool(gap[0] < reach_xy_m and gap[1] < reach_xy_m and gap[2] < reach_z_m)


def improve(
    occ: Occupancy,
    tracks: dict[int, GridTrack],
    chains: Callable[[int], list[np.ndarray]],
    *,
    passes: int,
    agents: list[int] | None = None,
    through: bool = True,
    skip_unchanged: bool = True,
    progress: Callable[[str, float], None] | None = None,
    deadline: float | None = None,
) -> dict:
    """Gauss-Seidel passes over ``agents`` (default: all), in place on ``tracks`` / ``occ`` (which
    must hold the same tracks); returns counts (passes run, replacements) and the makespan (s) after
    each pass, and how many re-timings were skipped (``skip_unchanged``: see module; False re-times
    every vehicle in every pass, for the test that the plan is the same). A wall-clock ``deadline`` stops it only as "not found" (:class:`~proxplan.planner.errors.PlanNotFound`), so the
    plan never depends on the machine's speed."""
    replaced = 0
    done = 0
    skipped = 0
    makespans: list[float] = []
    who = list(tracks) if agents is None else list(agents)
    problem = occ.problem
    reach_xy = problem.reach_xy_m + SAMPLING_GROWTH_M
    reach_z = problem.reach_z_m + SAMPLING_GROWTH_M
    # a vehicle whose re-timing gave nothing: (the number of changes then, its chains' box)
    idle: dict[int, tuple[int, np.ndarray, np.ndarray]] = {}
    # the bounding boxes (lo, hi) of the old and the new track of every replacement, in order
    changes: list[tuple[np.ndarray, np.ndarray]] = []
    # flying through waypoints, the roundings lie between chord and corner (measured, timing.corners):
    # the box is grown by the corners' largest deviation all the same, so that one bulging past its
    # corner by up to that much is still inside
    margin = CORNER_DEVIATION_M if through else 0.0
    for p in range(passes):
        changed = 0
        order = sorted(who, key=lambda a: (-tracks[a].arrival_step, a))
        for idx, a in enumerate(order):
            if occ.problem.pinned[a]:
                continue
            if deadline is not None and time.perf_counter() > deadline:
                raise PlanNotFound(
                    "no plan found within the time budget (continuous re-timing)", details={"nodes": idx}
                )
            if progress is not None and idx % 16 == 0:
                progress(f"continuous re-timing, pass {p + 1}/{passes}", 0.6 + 0.3 * (p + idx / len(order)) / passes)
            old = tracks[a]
            was = idle.get(a)
            if (
                skip_unchanged
                and was is not None
                and not any(_near_box(was[1], was[2], box, reach_xy, reach_z) for box in changes[was[0] :])
            ):
                skipped += 1  # nothing within reach changed since it gave nothing: it would again
                continue
            best = None
            occ.remove(a)
            mine = chains(a)
            for W in mine:
                res = time_chain(occ, a, W, arrive_by=old.arrival_step - 1, through=through)
                if (
                    res is not None
                    and res.arrival_step < old.arrival_step
                    and (best is None or res.arrival_step < best.arrival_step)
                ):
                    best = res
            new = old if best is None else best.track
            occ.put(new)
            tracks[a] = new
            if best is not None:
                changed += 1
                changes += [(old.lo_m, old.hi_m), (new.lo_m, new.hi_m)]
                idle.pop(a, None)
            else:
                idle[a] = (len(changes), *_box(mine, margin))
        replaced += changed
        done += 1
        makespans.append(max(tr.arrival_s for tr in tracks.values()))
        if changed == 0:
            break
    return {"passes": done, "replaced": replaced, "skipped": skipped, "makespan_after_pass_s": makespans}
