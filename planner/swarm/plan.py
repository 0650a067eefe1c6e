"""Swarm planning (``--method roadmap``; ``optimized`` for swarms of ``SWARM_MIN_VEHICLES`` or
more): coordinate jointly on a lattice, fly in continuous time.

1. *Straight first* (:mod:`proxplan.planner.swarm.straight`): if every vehicle can fly its straight
   line at once, synchronised (one step, checked exactly pair by pair), that is the plan (the CAPT
   case of interchangeable goals). (Keeping the straight lines of the vehicles in no conflicting
   pair and planning the rest around them was tried: it fails where a kept line passes a waiting
   vehicle's start, and gained nothing on the benchmark layouts.)
2. *Continuous time, prioritised* (:mod:`proxplan.planner.swarm.prioritized`): one vehicle after
   another, each along the best of its straight line and a wavefront route through the others'
   space-time, timed exactly; a vehicle that cannot be planned moves to the front. Two orders are
   tried (vehicles whose start another's goal needs first; longest line first) and the shorter
   plan kept.
3. *Joint coordination*, when prioritised planning gives up: LaCAM with PIBT on the lattice of the
   levels in use, long straight moves, synchronous conflicts checked exactly
   (:mod:`proxplan.planner.swarm.lacam`, a count of configurations bounds it), flown in lock-step
   (:mod:`proxplan.planner.swarm.lockstep`): conflict-free by construction, the guaranteed answer.
4. *Re-timing*: Gauss-Seidel passes (:mod:`proxplan.planner.swarm.retime`), every vehicle against
   the others' tracks in a space-time neighbourhood; never worse, always conflict-free.

The caller (the pipeline) runs the independent verifier on the result as on every plan. The info
names the ``stage`` that produced the tracks ("straight", "prioritised" or "lattice"); bounds in
the info: ``lower_bound_s`` (largest straight-line rest-to-rest time of any vehicle) and the
makespans after each stage.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from proxplan.planfile import Scenario
from proxplan.planner.sampling.ordering import lower_bound_makespan_s
from proxplan.planner.swarm.lacam import Lacam, SearchGaveUp
from proxplan.planner.swarm.lattice import build_lattice
from proxplan.planner.swarm.lockstep import lockstep_tracks
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.prioritized import PrioritizedFailed, dependency_order, prioritized_tracks
from proxplan.planner.swarm.problem import swarm_applicable, swarm_problem
from proxplan.planner.swarm.retime import improve, route_chain
from proxplan.planner.swarm.straight import straight_step_conflicts, straight_tracks
from proxplan.planner.swarm.sync import SyncTable
from proxplan.planner.swarm.tracks import GRID_DT_S
from proxplan.planner.timing.paths import TimedPath

SWARM_MIN_VEHICLES = 16  # formation changes with at least this many vehicles use the swarm layer by default
HORIZON_MARGIN_S = 5.0  # the re-timing horizon extends this far past the lock-step makespan, s

__all__ = ["SWARM_MIN_VEHICLES", "SwarmOptions", "swarm_applicable", "swarm_timed"]


@dataclass(frozen=True)
class SwarmOptions:
    """Knobs of the swarm layer; every budget is a count (same plan on every machine)."""

    max_run: int = 4  # longest straight move of one coordination step, in lattice edges
    max_nodes: int = 3000  # LaCAM configurations before the coordination search gives up
    passes: int = 3  # continuous re-timing passes
    prioritized: bool = True  # try prioritised continuous planning before the lattice coordination
    max_restarts: int = 2  # re-orderings of the prioritised planning, per order and waiting time
    seed: int = 0
    deflection_m: float = 0.0  # every keep-out grown by this (the vehicles' predicted deflections), m


def swarm_timed(
    scenario: Scenario,
    options: SwarmOptions | None = None,
    *,
    progress: Callable[[str, float], None] | None = None,
    deadline: float | None = None,
) -> tuple[dict[str, TimedPath], dict]:
    """Timed paths of every vehicle and an info dict (see module); :class:`SearchGaveUp` when the
    coordination search stops on its budget or the ``deadline`` (time.perf_counter() value)."""
    opts = options or SwarmOptions()
    why = swarm_applicable(scenario)
    if why is not None:
        raise ValueError(f"the swarm layer cannot plan this scenario: {why}")
    t0 = time.perf_counter()
    problem = swarm_problem(scenario, deflection_m=opts.deflection_m)
    info: dict = {"lower_bound_s": lower_bound_makespan_s(scenario), "vehicles": problem.n_agents}
    conflicts = straight_step_conflicts(problem)
    configurations = None
    lattice = None
    tracks = None
    if not conflicts:
        straight = straight_tracks(problem, list(range(problem.n_agents)))
        tracks = [straight[a] for a in range(problem.n_agents)]
        info["coordination"] = "one synchronised straight step"
        info["stage"] = "straight"
    elif opts.prioritized:
        horizon = int(round(max(4.0 * info["lower_bound_s"], info["lower_bound_s"] + 20.0) / GRID_DT_S))
        t1 = time.perf_counter()
        length = np.linalg.norm(problem.goals_m - problem.starts_m, axis=1)
        orders = {
            "dependencies first": dependency_order(problem),
            "longest first": sorted(range(problem.n_agents), key=lambda a: (-float(length[a]), a)),
        }
        tried = []
        for label, order in orders.items():
            try:
                planned, counts = prioritized_tracks(
                    problem,
                    order,
                    horizon_steps=horizon,
                    max_restarts=opts.max_restarts,
                    progress=progress,
                    deadline=deadline,
                )
            except PrioritizedFailed as err:
                tried.append(f"{label}: gave up after {err.restarts} attempts (" + ", ".join(err.history[-2:]) + ")")
                continue
            makespan = max(tr.arrival_s for tr in planned.values())
            tried.append(f"{label}: {makespan:.2f} s")
            if tracks is None or makespan < max(tr.arrival_s for tr in tracks):
                tracks = [planned[a] for a in range(problem.n_agents)]
                info["stage"] = "prioritised"
                info["coordination"] = (
                    f"prioritised continuous planning, {label} ({counts['orders_tried']} attempt(s), "
                    f"vehicles wait at their starts at most {counts['leave_start_s']:g} s)"
                )
        info["prioritized"] = "; ".join(tried)
        info["prioritized_time_s"] = round(time.perf_counter() - t1, 3)
    if tracks is None:
        if progress:
            progress(f"coordination: lattice ({len(conflicts)} straight-line conflicts)", 0.05)
        lattice = build_lattice(problem, max_run=opts.max_run)
        sync = SyncTable(problem.keepouts, problem.type_index, lattice.pos_mm)
        info["lattice"] = {
            "spacing_m": lattice.spacing_m,
            "levels_m": lattice.levels_m.tolist(),
            "vertices": int(lattice.pos_m.shape[0]),
        }
        t1 = time.perf_counter()
        result = Lacam(lattice, sync, seed=opts.seed).solve(
            max_nodes=opts.max_nodes, deadline=deadline, progress=progress
        )
        configurations = result.configurations
        info["stage"] = "lattice"  # flown in lock-step
        info["coordination"] = (
            f"LaCAM: {len(configurations) - 1} steps, {result.nodes} configurations, {result.tests} exact pair tests"
        )
        info["coordination_time_s"] = round(time.perf_counter() - t1, 3)
        tracks = lockstep_tracks(lattice, configurations)
    by_agent = {tr.agent: tr for tr in tracks}
    info["initial_makespan_s"] = max(tr.arrival_s for tr in tracks)
    horizon = int(round((info["initial_makespan_s"] + HORIZON_MARGIN_S) / GRID_DT_S))
    occ = Occupancy(problem, tracks, horizon)

    def chains(a: int) -> list[np.ndarray]:
        out = [np.array([problem.starts_m[a], problem.goals_m[a]])]
        if lattice is not None and configurations is not None:
            out.append(route_chain(lattice, configurations, a))
        return out

    t2 = time.perf_counter()
    counts = improve(occ, by_agent, chains, passes=opts.passes, progress=progress, deadline=deadline)
    info["retiming"] = {**counts, "time_s": round(time.perf_counter() - t2, 3)}
    info["makespan_s"] = max(tr.arrival_s for tr in by_agent.values())
    info["time_s"] = round(time.perf_counter() - t0, 3)
    timed = {problem.names[a]: by_agent[a].timed_path() for a in range(problem.n_agents)}
    return timed, info


__all__ += ["SearchGaveUp"]
