"""Routes raised over the others: overtaking on one line by rising over the vehicles on it (issue 37,
round 29A).

Where vehicles on one line must reverse their order (a vehicle starting behind another and ending beyond
its goal: corridor-64's columns, measured with ``benchmarks/why_gives_up.py``), the flat routes of
:func:`~proxplan.planner.swarm.single.plan_one` (the straight line and the wavefront route at the route's
own heights) can only wait: a vehicle parked or waiting on the line walls it at that height. A vehicle
may instead pass *over* it. :func:`raised_chains` gives, from the vehicle's route (its wavefront route,
or its straight line where there is none), the chains that rise from the start by each of
:data:`RAISE_DZ_M`, fly the route's inner waypoints at that height, and come down onto the goal; each
either straight above the route or beside it by the keep-out's horizontal radius at that height
difference and :data:`SIDE_MARGIN_M` (an offset that clears a vehicle of any type resting on the route's
line below). Only
chains inside the static free space (the problem's box: a level's band, :mod:`~proxplan.planner.swarm.stacked`)
are kept. :func:`raised_or` times them exactly against the occupancy
(:func:`~proxplan.planner.swarm.chain.time_chain`, as every route) and keeps the earliest arrival: never
later than the track it is given, and not asked where that track already arrives at the vehicle's
unobstructed straight-line time (nothing arrives earlier).

World frame, z up, m; steps of ``GRID_DT_S``.
"""

from __future__ import annotations

import numpy as np

from proxplan.planner.swarm.chain import time_chain
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.problem import SwarmProblem
from proxplan.planner.swarm.tracks import GRID_DT_S, GridTrack
from proxplan.planner.swarm.wave import wave_route
from proxplan.planner.timing.profile import rest_to_rest

# heights a route is raised by, m. Set watching corridor-64's and pillar-64's Crazyflie levels alone
# (docs/planner.md, stop 67 round 29A: 0.5 m alone corridor 21.12 -> 18.25 s with offsets of 0.3 m; 0.5
# and 0.9 m 15.75 s): 0.5 m is about where a Crazyflie's keep-out over another narrows to 0.09-0.26 m
# (round 28A), 0.9 m is near the top of the Crazyflie level's band (1.83-2.93 m) on both layouts
RAISE_DZ_M = (0.5, 0.9)
# a route beside the line keeps this much more than the keep-out's horizontal radius, m: at the radius
# itself the pair conflicts (2 mm more still did, 5 mm did not: test_swarm_repair29_raised's in-line pair);
# one step of the keep-out tables' height rows (2 cm) is kept
SIDE_MARGIN_M = 0.02

# starts and goals within this of one height, and that height within this of the free box's floor or
# ceiling, make a problem a level of the stacked plan, m: twice the stacked plan's easing of a level's band
# (stacked.LEVEL_TOLERANCE_M, 1 mm)
LEVEL_EDGE_M = 2e-3

__all__ = ["LEVEL_EDGE_M", "RAISE_DZ_M", "SIDE_MARGIN_M", "a_level", "raised_chains", "raised_or"]


def a_level(problem: SwarmProblem) -> bool:
    """Every start and goal of ``problem`` at one height, the floor or the ceiling of its free box (within
    :data:`LEVEL_EDGE_M`): a top or bottom level of the stacked plan (:func:`~proxplan.planner.swarm.stacked.level_subproblem`
    cuts the box to the level's band), whose flat routes can pass nobody on their line; prioritised planning
    raises routes there only (:mod:`proxplan.planner.swarm.prioritised_stage`). A whole flat swarm with room
    above and below is not one: grid-64's then found a plan (8.80 s) the stacked plan beat (5.60 s), for
    ~10 s more CPU (round 29A)."""
    z = np.concatenate([problem.starts_m[:, 2], problem.goals_m[:, 2]])
    if z.size == 0 or float(z.max() - z.min()) > LEVEL_EDGE_M:
        return False
    edge = min(abs(float(z.min()) - float(problem.lo_m[2])), abs(float(problem.hi_m[2]) - float(z.max())))
    return edge <= LEVEL_EDGE_M


def _side_m(occ: Occupancy, agent: int, dz_m: float) -> float:
    """The largest horizontal radius, m, of the keep-outs of a vehicle of any type resting ``dz_m``
    below ``agent`` (d = p_agent - p_other, so the pair (other, agent))."""
    p = occ.problem
    mine = int(p.type_index[agent])
    types = sorted({int(t) for t in p.type_index})
    return max(p.keepouts[(t, mine)].horizontal_radius_m(dz_m, dz_m) for t in types)


def raised_chains(occ: Occupancy, agent: int, route_m: np.ndarray) -> list[np.ndarray]:
    """The raised chains of ``agent`` from its ``route_m`` ((m+1, 3), start first, goal last; see module),
    each (k, 3) m, in the order of :data:`RAISE_DZ_M` and offsets 0, right, left of the start-to-goal
    heading; only those inside the static free space."""
    p = occ.problem
    route = np.asarray(route_m, dtype=float)
    s, g = route[0], route[-1]
    heading = g[:2] - s[:2]
    length = float(np.linalg.norm(heading))
    normal = np.zeros(3) if length < 1e-9 else np.array([heading[1], -heading[0], 0.0]) / length
    out: list[np.ndarray] = []
    top = float(route[:, 2].max())
    for dz in RAISE_DZ_M:
        if top + dz > float(p.hi_m[2]):
            continue
        up = np.array([0.0, 0.0, dz])
        side = _side_m(occ, agent, dz) + SIDE_MARGIN_M
        for lateral in dict.fromkeys((0.0, side, -side)):
            off = up + lateral * normal
            chain = np.array([s, s + off, *(q + up for q in route[1:-1]), g + off, g])
            if all(p.segment_free(a, b) for a, b in zip(chain[:-1], chain[1:], strict=True)):
                out.append(chain)
    return out


def raised_or(occ: Occupancy, agent: int, through: bool, track: GridTrack | None) -> GridTrack | None:
    """``track`` (``agent``'s flat planning against ``occ``, or None), or the earliest raised chain's
    track where one arrives strictly earlier (see module)."""
    p = occ.problem
    s, g = p.starts_m[agent], p.goals_m[agent]
    unobstructed = rest_to_rest(float(np.linalg.norm(g - s)), p.limits[agent], GRID_DT_S).steps
    best_step = None if track is None else track.arrival_step
    if best_step is not None and best_step <= unobstructed:
        return track
    if max(float(s[2]), float(g[2])) + min(RAISE_DZ_M) > float(p.hi_m[2]):  # no room above: no raised chain
        return track
    route = wave_route(occ, agent, s, g, heights=False)
    if route is None:
        route = np.array([s, g])
    best = track
    for chain in raised_chains(occ, agent, route):
        res = time_chain(occ, agent, chain, arrive_by=None if best_step is None else best_step - 1, through=through)
        if res is not None and (best_step is None or res.arrival_step < best_step):
            best, best_step = res.track, res.arrival_step
    return best
