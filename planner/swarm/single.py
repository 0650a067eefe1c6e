"""One vehicle planned against the tracks of an :class:`~proxplan.planner.swarm.occupancy.Occupancy`
(prioritised planning's single-vehicle planning, :mod:`proxplan.planner.swarm.priority`, and the
repairs that plan vehicles again): its straight line, else the better of that and a wavefront route
through the others' space-time (:func:`proxplan.planner.swarm.wave.wave_route`), else a slower,
wider route, each timed exactly (:func:`proxplan.planner.swarm.chain.time_chain`); the earliest
arrival kept.
"""

from __future__ import annotations

import numpy as np

from proxplan.planner.swarm.chain import time_chain
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.problem import SwarmProblem
from proxplan.planner.swarm.reserve import ideal_track as _ideal
from proxplan.planner.swarm.tracks import GRID_DT_S, GridTrack
from proxplan.planner.swarm.wave import wave_route
from proxplan.planner.timing.profile import rest_to_rest

SLOW_PACE = 0.5  # last route attempt: this fraction of the speed limit ...
SLOW_GROWTH_M = 0.05  # ... and keep-outs this much wider, m

__all__ = ["SLOW_GROWTH_M", "SLOW_PACE", "ideal_track", "plan_ignoring", "plan_one", "start_visitors"]


def ideal_track(problem: SwarmProblem, occ: Occupancy, agent: int) -> GridTrack | None:
    """The track a vehicle would fly alone (:func:`proxplan.planner.swarm.reserve.ideal_track`, on
    ``occ``'s horizon)."""
    return _ideal(problem, agent, occ.horizon)


def start_visitors(occ: Occupancy, agent: int) -> set[int]:
    """The agents whose tracks in ``occ`` come within ``agent``'s keep-out of its start at some
    time (fly through it or park there): a vehicle that cannot be planned could not leave its start
    before one of them came."""
    p = occ.problem
    return occ.conflicting_agents(GridTrack(agent, int(p.type_index[agent]), p.starts_m[agent].copy(), []))


def plan_ignoring(
    occ: Occupancy, agent: int, ignore: set[int], through: bool, *, heights: bool = False
) -> GridTrack | None:
    """:func:`plan_one` against the tracks in ``occ`` but those of ``ignore`` (it may collide with
    them only), or None."""
    taken = [occ.remove(b) for b in sorted(ignore) if b != agent]
    try:
        return plan_one(occ, agent, through, heights=heights)
    finally:
        for tr in taken:
            if tr is not None:
                occ.put(tr)


def plan_one(
    occ: Occupancy, agent: int, through: bool, *, heights: bool = False, arrive_by: int | None = None
) -> GridTrack | None:
    """The earliest-arriving track of ``agent`` against the tracks in ``occ`` (see module: its
    straight line, else the better of that and a wavefront route, else a slower, wider route), or
    None. ``heights``: also a wavefront route with discs for the heights it flies at
    (:mod:`proxplan.planner.swarm.wave`), the earlier arrival of the two kept: never later than
    without, for this vehicle against these tracks (not for the plan: the vehicles planned after it
    meet another track; the swarm layer plans both ways and keeps the shorter plan, see
    :class:`proxplan.planner.swarm.options.SwarmOptions`).

    ``arrive_by`` (grid step; None: no bound): that track where it arrives by this step, else None,
    with every search pruned to it (round 37B: the makespan repair drops any later track). Exactly
    the unbounded answer so cut: a bounded timing gives the unbounded one's track whenever that
    arrives in time (:func:`~proxplan.planner.swarm.chain.time_chain`: ``arrive_by`` only prunes);
    no track arrives before the straight line's rest-to-rest time (so where the straight line is
    late and no faster than that, no route is in time either); and the slow route, which the
    unbounded search tries only where the others found no track at all, is timed first, and only a
    slow track in time makes the others be timed without the bound to tell "none" from "late"."""
    problem = occ.problem
    s, g = problem.starts_m[agent], problem.goals_m[agent]
    best = time_chain(occ, agent, np.array([s, g]), arrive_by=arrive_by, through=through)
    # no flight from rest to rest is faster than the straight line's rest-to-rest time: a straight
    # line flown at once is the best there is, and no route is searched
    unobstructed = rest_to_rest(float(np.linalg.norm(g - s)), problem.limits[agent], GRID_DT_S).steps
    routes: list[np.ndarray] = []
    if best is None or best.arrival_step > unobstructed:
        # the wavefront with the widest disc at every height, then (heights) with discs for the heights
        # the route flies at (it passes over and under the others where their keep-outs are narrow)
        for by_height in (False, True) if heights else (False,):
            route = wave_route(occ, agent, s, g, heights=by_height)
            if route is not None and len(route) > 2:
                routes.append(route)
                res = time_chain(
                    occ, agent, route, arrive_by=arrive_by if best is None else best.arrival_step - 1, through=through
                )
                if res is not None and (best is None or res.arrival_step < best.arrival_step):
                    best = res
    if best is None:  # a slower, wider route leaves the exact timing more room
        slow = wave_route(occ, agent, s, g, pace=SLOW_PACE, grow_m=SLOW_GROWTH_M, heights=False)
        if slow is not None:
            best = time_chain(occ, agent, slow, arrive_by=arrive_by, through=through)
            if (
                best is not None
                and arrive_by is not None
                and _found_late(occ, agent, through, [np.array([s, g]), *routes])
            ):
                best = None  # the unbounded search finds a late track there, and never tries the slow route
    return None if best is None else best.track


def _found_late(occ: Occupancy, agent: int, through: bool, chains: list[np.ndarray]) -> bool:
    """Whether any of ``chains`` (waypoints, m) has a timing within the horizon (no bound)."""
    return any(time_chain(occ, agent, w, through=through) is not None for w in chains)
