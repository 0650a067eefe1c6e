"""Reserved starts: a vehicle not planned yet holds its start until it is planned.

Prioritised planning (:mod:`proxplan.planner.swarm.priority`) assumes that a vehicle not planned yet
leaves its start on its straight line after a hold (a *prediction*, :func:`predicted_track`); the
vehicles planned before it then fly through its start as soon as the prediction has left it, and at
64 vehicles with fixed goals every pass gave up on such *start traps*: the vehicle, planned later,
could not get away before they came (docs/planner.md, sixth round). With ``reserve_starts`` its
start is occupied for good until it is planned (:func:`reserved_track`): nobody plans through it
unless it is *released* for them (:class:`Reservations`): a vehicle that cannot be planned around
the reserved starts in the way of its ideal track (:func:`ideal_track`) is planned once more with
those predicted to leave (along their ideal tracks where a straight line is not statically free,
:func:`leaving_track`), and if that succeeds they are planned next, before anyone else can rely on
their leaving: the one it reaches first first, and among them each after those whose starts lie in
its own way (:func:`starts_in_the_way`).
"""

from __future__ import annotations

from collections import deque

import numpy as np

from proxplan.planner.swarm.chain import time_chain
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.problem import SwarmProblem
from proxplan.planner.swarm.tracks import GRID_DT_S, GridTrack
from proxplan.planner.swarm.wave import wave_route
from proxplan.planner.timing.profile import LineMove, rest_to_rest


def predicted_track(problem: SwarmProblem, agent: int, *, hold_s: float = 0.0) -> GridTrack:
    """Where a vehicle not planned yet is assumed to be (a track that vanishes): holding its start
    ``hold_s``, then flying its straight line rest-to-rest until it is beyond reach of its start. A
    vehicle whose goal is its start stays there for good."""
    s, g = problem.starts_m[agent], problem.goals_m[agent]
    length = float(np.linalg.norm(g - s))
    ty = int(problem.type_index[agent])
    hold = int(round(hold_s / GRID_DT_S))
    if length <= 0.0:
        return GridTrack(agent, ty, s.copy(), [])
    mv = LineMove(s, g, rest_to_rest(length, problem.limits[agent], GRID_DT_S))
    track = GridTrack(agent, ty, s.copy(), [(hold, mv)])
    reach = max(k.reach_xy_m for (ta, _), k in problem.keepouts.items() if ta == ty)
    away = np.flatnonzero(np.linalg.norm(track.positions_m[:, :2] - s[:2], axis=1) > reach)
    return track.vanishing(int(away[0]) + 1 if away.size else track.positions_m.shape[0])


def reserved_track(problem: SwarmProblem, agent: int) -> GridTrack:
    """A vehicle not planned yet holding its start for good (its start reserved until it is planned)."""
    return GridTrack(agent, int(problem.type_index[agent]), problem.starts_m[agent].copy(), [])


def ideal_track(problem: SwarmProblem, agent: int, horizon_steps: int) -> GridTrack | None:
    """The track a vehicle would fly alone: its straight line from t = 0 (its route through the static
    free space when the line is not statically free; None when there is none)."""
    s, g = problem.starts_m[agent], problem.goals_m[agent]
    empty = Occupancy(problem, [], horizon_steps)
    W = np.array([s, g])
    if not problem.segment_free(s, g):
        route = wave_route(empty, agent, s, g, heights=False)
        if route is None:
            return None
        W = route
    res = time_chain(empty, agent, W)
    return None if res is None else res.track


def starts_in_the_way(
    problem: SwarmProblem, ideal: dict[int, GridTrack | None], horizon_steps: int
) -> dict[int, set[int]]:
    """Per vehicle, the vehicles whose reserved starts its ``ideal`` track comes within keep-out of."""
    occ = Occupancy(problem, [reserved_track(problem, b) for b in range(problem.n_agents)], horizon_steps)
    out: dict[int, set[int]] = {}
    for a in range(problem.n_agents):
        tr = ideal.get(a)
        out[a] = set() if tr is None or problem.pinned[a] else occ.conflicting_agents(tr) - {a}
    return out


def leaving_track(problem: SwarmProblem, agent: int, ideal: GridTrack | None, *, hold_s: float) -> GridTrack:
    """A released vehicle predicted to leave: its ``ideal`` track after ``hold_s`` all the way to its
    goal, parked there (a commitment made for the vehicle planned through its start, which must keep
    clear of the whole flight: a prediction that vanishes once out of reach of the start let a faster
    vehicle behind it catch up with it further on); :func:`predicted_track` when it has none."""
    if ideal is None:
        return predicted_track(problem, agent, hold_s=hold_s)
    hold = int(round(hold_s / GRID_DT_S))
    return GridTrack(agent, ideal.type, problem.starts_m[agent].copy(), [(k0 + hold, mv) for k0, mv in ideal.moves])


class Reservations:
    """The reserved starts of one pass of prioritised planning (see module): which are released for
    whom, and in which order those are planned."""

    def __init__(self, problem: SwarmProblem, horizon_steps: int, hold_s: float):
        self.problem, self.hold_s = problem, hold_s
        self.ideal = {a: ideal_track(problem, a, horizon_steps) for a in range(problem.n_agents)}
        self.need = starts_in_the_way(problem, self.ideal, horizon_steps)
        self.released = 0

    def along(self, a: int, agents: list[int]) -> list[int]:
        """``agents`` in the order ``a`` reaches their starts along its straight line."""
        s, g = self.problem.starts_m[a], self.problem.goals_m[a]
        return sorted(agents, key=lambda b: (float(np.dot(self.problem.starts_m[b] - s, g - s)), b))

    def in_need_order(self, agents: list[int]) -> list[int]:
        """``agents`` with each after those of them whose starts lie in its way (a cycle broken by
        the given order)."""
        left, out = list(agents), []
        while left:
            pick = next((b for b in left if not (self.need[b] & set(left))), left[0])
            out.append(pick)
            left.remove(pick)
        return out

    def release(self, occ: Occupancy, agents: list[int]) -> None:
        """``agents`` predicted to leave (a vehicle is planned through their starts)."""
        for b in agents:
            occ.put(leaving_track(self.problem, b, self.ideal[b], hold_s=self.hold_s))

    def release_in_way(self, occ: Occupancy, agent: int, candidates: list[int]) -> list[int]:
        """The vehicles of ``candidates`` whose tracks in ``occ`` are in the way of ``agent``'s ideal
        track, released (predicted to leave) and returned in the order they should be planned next
        (:meth:`plan_next`'s); [] when none is in its way."""
        ideal = self.ideal[agent]
        if ideal is None:
            return []
        hit = occ.conflicting_agents(ideal)
        first = self.in_need_order(self.along(agent, [b for b in candidates if b in hit]))
        self.release(occ, first)
        return first

    def reserve(self, occ: Occupancy, agents: list[int]) -> None:
        for b in agents:
            occ.put(reserved_track(self.problem, b))

    def plan_next(self, a: int, agents: list[int], occ: Occupancy, queue: deque[int]) -> None:
        """The vehicles released for ``a`` (``a`` is planned through their starts): predicted to leave,
        as ``a`` assumed, and planned next, the one ``a`` reaches first first, before anyone else
        relies on their leaving; among them, each after those whose starts lie in its way."""
        first = self.in_need_order(self.along(a, agents))
        self.release(occ, first)
        for b in first:
            if b in queue:
                queue.remove(b)
        queue.extendleft(reversed(first))
        self.released += len(first)


__all__ = [
    "Reservations",
    "ideal_track",
    "leaving_track",
    "predicted_track",
    "reserved_track",
    "starts_in_the_way",
]
