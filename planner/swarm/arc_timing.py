"""The earliest timing of one vehicle along a smooth detour (:class:`~proxplan.planner.timing.arcs.ArcMove`)
against the others' tracks: it holds its start, leaves at the first grid step the others allow, flies
the arc without stopping and holds its goal for good (issue 37 item 5; used by
:mod:`proxplan.planner.swarm.yielding`).

The holds and the departures are asked of the :class:`~proxplan.planner.swarm.occupancy.Occupancy`
as :func:`~proxplan.planner.swarm.chain.time_chain` asks them (``forbidden_holds`` at the start and the
goal, ``forbidden_departures`` along the flown grid samples), so the result is conflict-free against
those tracks; the arc's samples are checked against the static free space.
"""

from __future__ import annotations

import numpy as np

from proxplan.planner.swarm.chain import ChainResult
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.tracks import GRID_DT_S, GridTrack
from proxplan.planner.timing.arcs import ArcMove

__all__ = ["time_arc"]


def _first_true(mask: np.ndarray) -> int:
    hit = np.flatnonzero(mask)
    return int(hit[0]) if hit.size else mask.size


def _arc(problem, agent: int, bulge_m: np.ndarray) -> tuple[ArcMove, np.ndarray, bool]:
    """The arc of ``agent`` bulging by ``bulge_m`` (3,), m, its grid samples (read-only) and whether they are
    statically free: a function of the problem alone, built once per problem (kept in ``problem.static_memo``
    by :func:`time_arc`; round 30B: 2,500 arcs built on corridor-64 by type, most of them again and again)."""
    s, g = problem.starts_m[agent], problem.goals_m[agent]
    mv = ArcMove(s, g, bulge_m, problem.limits[agent], GRID_DT_S)
    q = mv.positions()
    q.flags.writeable = False
    return mv, q, bool(problem.static_free(q).all())


def time_arc(occ: Occupancy, agent: int, bulge_m: np.ndarray, *, arrive_by: int | None = None) -> ChainResult | None:
    """The earliest arrival of ``agent`` from its start to its goal along the arc bulging by ``bulge_m``
    (3,), m (see module), arriving by step ``arrive_by`` (None: within the horizon), or None."""
    problem = occ.problem
    s, g = problem.starts_m[agent], problem.goals_m[agent]
    if float(np.linalg.norm(g - s)) <= 1e-9:
        return None
    mv, q, ok = problem.static_memo.get(
        ("arc move", agent, np.asarray(bulge_m, dtype=float).tobytes()), lambda: _arc(problem, agent, bulge_m)
    )
    if not ok:
        return None
    T = occ.horizon
    last = T - 1 if arrive_by is None else min(T - 1, arrive_by)
    held = occ.forbidden_holds(agent, s)
    leave_by = _first_true(held)  # the start is safe to hold for the steps before this one
    if leave_by == 0:
        return None
    goal_bad = np.flatnonzero(occ.forbidden_holds(agent, g))
    goal_from = int(goal_bad[-1]) + 1 if goal_bad.size else 0  # held for good from this step on
    lo = max(0, goal_from - mv.steps)
    hi = min(leave_by, last - mv.steps + 1)  # departures in [lo, hi)
    if hi <= lo:
        return None
    bad = occ.forbidden_departures(agent, q, from_step=lo, until_step=hi)
    free = np.flatnonzero(~bad[lo:hi])
    if not free.size:
        return None
    d = lo + int(free[0])
    route = np.array([s, 0.5 * (s + g) + np.asarray(bulge_m, dtype=float), g])
    track = GridTrack(agent, int(problem.type_index[agent]), s.copy(), [(d, mv)], route_m=route)
    return ChainResult(track, d + mv.steps)
