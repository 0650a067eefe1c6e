"""Prioritised planning in continuous time: one vehicle after another, each against the tracks of
the vehicles before it, the others waiting at their starts.

A vehicle not planned yet is assumed to hold its start until ``LEAVE_START_S`` (then to be gone, as
the sampling planner assumes); a vehicle planned later sees every earlier track, so if one passes its
start before it can leave, its own search fails and the order changes. Each vehicle tries its
candidate waypoint chains - the straight line, the wavefront route through the others' space-time
(:func:`proxplan.planner.swarm.wave.wave_route`) and optional extra chains - timed exactly
(:func:`proxplan.planner.swarm.chain.time_chain`), and keeps the earliest arrival. When one cannot be
planned it moves to the front and planning restarts, at most ``max_restarts`` times (a count). A
caller's wall-clock ``deadline`` only ever stops it as "not found" (:class:`SearchGaveUp`).
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from proxplan.planner.swarm.chain import time_chain
from proxplan.planner.swarm.lacam import SearchGaveUp
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.problem import SwarmProblem
from proxplan.planner.swarm.tracks import GRID_DT_S, Track
from proxplan.planner.swarm.wave import wave_route

LEAVE_START_S = 2.5  # vehicles not planned yet hold their start until then, s
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
    extra_chains: Callable[[int], list[np.ndarray]] | None = None,
    max_restarts: int = 6,
    progress: Callable[[str, float], None] | None = None,
    deadline: float | None = None,
) -> tuple[dict[int, Track], dict]:
    """Tracks of every agent (see module) and counts; :class:`PrioritizedFailed` when an agent still
    fails after ``max_restarts`` re-orderings."""
    leave = int(round(LEAVE_START_S / GRID_DT_S))
    order = [a for a in order if problem.pinned[a]] + [a for a in order if not problem.pinned[a]]
    failed = -1
    history: list[str] = []
    for restart in range(max_restarts + 1):
        occ = Occupancy(problem, [], horizon_steps)
        occ.waiting = {a: (problem.starts_m[a], leave) for a in order if not problem.pinned[a]}
        tracks: dict[int, Track] = {}
        for a in order:
            if problem.pinned[a]:
                tracks[a] = Track(a, int(problem.type_index[a]), problem.starts_m[a].copy(), [])
                occ.put(tracks[a])
        failed = -1
        for idx, a in enumerate(order):
            if problem.pinned[a]:
                continue
            if deadline is not None and time.perf_counter() > deadline:
                raise SearchGaveUp("no plan found within the time budget (prioritised planning)", nodes=idx)
            if progress is not None and idx % 8 == 0:
                progress(f"continuous planning {idx}/{len(order)} (order {restart + 1})", 0.1 + 0.5 * idx / len(order))
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
                history.append(f"{problem.names[a]} (#{idx + 1}, route {'found' if route is not None else 'none'})")
                break
            tracks[a] = best.track
            occ.put(best.track)
        if failed < 0:
            return tracks, {"orders_tried": restart + 1, "failures": history}
        order = [failed] + [a for a in order if a != failed]
    raise PrioritizedFailed(failed, max_restarts, history)
