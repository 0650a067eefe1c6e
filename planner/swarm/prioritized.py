"""Prioritised planning in continuous time: one vehicle after another, each against the tracks of
the vehicles before it (and of ``fixed`` vehicles planned already), the others waiting at their
starts.

Order (:func:`dependency_order`): a vehicle whose start another one's goal needs is planned first
(it must leave before the other arrives); otherwise, and to break cycles, the longer straight line
first. A vehicle not planned yet is assumed to hold its start until ``LEAVE_START_S`` (then to be
gone, as the sampling planner assumes; a short wait first, the longer one if that fails); a vehicle
planned later sees every earlier track, so if one passes its start before it can leave, its own
search fails and the order changes. Each vehicle tries its
candidate waypoint chains - the straight line, the wavefront route through the others' space-time
(:func:`proxplan.planner.swarm.wave.wave_route`) and optional extra chains - timed exactly
(:func:`proxplan.planner.swarm.chain.time_chain`), and keeps the earliest arrival. When one cannot be
planned it moves to the front and planning restarts, at most ``max_restarts`` times (a count). A
caller's wall-clock ``deadline`` only ever stops it as "not found" (:class:`~proxplan.planner.errors.PlanNotFound`).
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from proxplan.planner.errors import PlanNotFound
from proxplan.planner.swarm.chain import time_chain
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.problem import SwarmProblem
from proxplan.planner.swarm.tracks import GRID_DT_S, Track
from proxplan.planner.swarm.wave import wave_route

LEAVE_START_S = (1.0, 2.5)  # vehicles not planned yet hold their start until then, s: tried in turn
SLOW_PACE = 0.5  # second route attempt: this fraction of the speed limit ...
SLOW_GROWTH_M = 0.05  # ... and keep-outs this much wider, m


class PrioritizedFailed(Exception):
    def __init__(self, agent: int, restarts: int, history: list[str]):
        super().__init__(f"agent {agent} could not be planned after {restarts} re-orderings")
        self.agent, self.restarts, self.history = agent, restarts, history


def prioritized_tracks(
    problem: SwarmProblem,
    order: list[int],
    *,
    horizon_steps: int,
    fixed: dict[int, Track] | None = None,
    extra_chains: Callable[[int], list[np.ndarray]] | None = None,
    max_restarts: int = 3,
    progress: Callable[[str, float], None] | None = None,
    deadline: float | None = None,
) -> tuple[dict[int, Track], dict]:
    """Tracks of every agent (see module) and counts; :class:`PrioritizedFailed` when an agent still
    fails after ``max_restarts`` re-orderings."""
    fixed = dict(fixed or {})
    first = [a for a in order if a not in fixed]
    first = [a for a in first if problem.pinned[a]] + [a for a in first if not problem.pinned[a]]
    failed = -1
    history: list[str] = []
    attempts = [(leave_s, restart) for leave_s in LEAVE_START_S for restart in range(max_restarts + 1)]
    for attempt, (leave_s, restart) in enumerate(attempts):
        if restart == 0:
            order = list(first)
        leave = int(round(leave_s / GRID_DT_S))
        occ = Occupancy(problem, list(fixed.values()), horizon_steps)
        occ.waiting = {a: (problem.starts_m[a], leave) for a in order if not problem.pinned[a]}
        tracks: dict[int, Track] = dict(fixed)
        for a in order:
            if problem.pinned[a]:
                tracks[a] = Track(a, int(problem.type_index[a]), problem.starts_m[a].copy(), [])
                occ.put(tracks[a])
        failed = -1
        for idx, a in enumerate(order):
            if problem.pinned[a]:
                continue
            if deadline is not None and time.perf_counter() > deadline:
                raise PlanNotFound(
                    "no plan found within the time budget (prioritised planning)", details={"nodes": idx}
                )
            if progress is not None and idx % 8 == 0:
                progress(
                    f"continuous planning {idx}/{len(order)} (attempt {attempt + 1})", 0.1 + 0.5 * idx / len(order)
                )
            del occ.waiting[a]
            s, g = problem.starts_m[a], problem.goals_m[a]
            chains = [np.array([s, g])]
            route = wave_route(occ, a, s, g)
            if route is not None and len(route) > 2:
                chains.append(route)
            if extra_chains is not None:
                chains += extra_chains(a)
            best = None
            for W in chains:
                res = time_chain(occ, a, W, arrive_by=None if best is None else best.arrival_step - 1)
                if res is not None and (best is None or res.arrival_step < best.arrival_step):
                    best = res
            if best is None:  # a slower, wider route leaves the exact timing more room
                slow = wave_route(occ, a, s, g, pace=SLOW_PACE, grow_m=SLOW_GROWTH_M)
                if slow is not None:
                    best = time_chain(occ, a, slow)
            if best is None:
                failed = a
                history.append(
                    f"{problem.names[a]} (#{idx + 1}, route {'found' if route is not None else 'none'}, waits {leave_s:g} s)"
                )
                break
            tracks[a] = best.track
            occ.put(best.track)
        if failed < 0:
            return tracks, {"orders_tried": attempt + 1, "failures": history, "leave_start_s": leave_s}
        order = [failed] + [a for a in order if a != failed]
    raise PrioritizedFailed(failed, len(attempts), history)


def dependency_order(problem: SwarmProblem) -> list[int]:
    """Planning order: a vehicle whose start another's goal needs goes before it (it has to leave
    first), ties and cycles broken by the longer straight line first (it sets the makespan)."""
    from scipy.spatial import cKDTree

    A = problem.n_agents
    length = np.linalg.norm(problem.goals_m - problem.starts_m, axis=1)
    key = {a: (-float(length[a]), a) for a in range(A)}
    before: dict[int, set[int]] = {a: set() for a in range(A)}  # a -> vehicles that must go before a
    tree = cKDTree(problem.starts_m[:, :2])
    for a, near in enumerate(tree.query_ball_point(problem.goals_m[:, :2], problem.reach_xy_m)):
        for b in near:
            if b == a:
                continue
            ko = problem.keepouts[(int(problem.type_index[a]), int(problem.type_index[b]))]
            if ko.conflict((problem.starts_m[b] - problem.goals_m[a])[None], rest=True)[0]:
                before[a].add(b)
    out: list[int] = []
    done: set[int] = set()
    while len(out) < A:
        ready = [a for a in range(A) if a not in done and before[a] <= done]
        pick = min(ready or [a for a in range(A) if a not in done], key=lambda a: key[a])
        out.append(pick)
        done.add(pick)
    return out
