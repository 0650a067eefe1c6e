"""Swarm planning (``--method roadmap``; ``optimized`` for swarms of ``SWARM_MIN_VEHICLES`` or
more): coordinate jointly on a lattice, fly in continuous time.

1. *Straight first*: if every vehicle can fly its straight line at once, synchronised (one step,
   checked exactly pair by pair, :mod:`proxplan.planner.swarm.sync`), that is the coordination plan
   (the CAPT case of interchangeable goals).
2. *Coordination*: otherwise LaCAM with PIBT on the lattice of the levels in use, long straight
   moves, synchronous conflicts checked exactly (:mod:`proxplan.planner.swarm.lacam`); the count of
   configurations bounds it.
3. *Conversion*: the plan flown in lock-step (:mod:`proxplan.planner.swarm.lockstep`), conflict-free
   by construction.
4. *Continuous time*: Gauss-Seidel re-timing passes (:mod:`proxplan.planner.swarm.retime`), every
   vehicle along its straight line or its pulled coordination route, against the others' tracks
   in a space-time neighbourhood; never worse, always conflict-free.

The caller (the pipeline) runs the independent verifier on the result as on every plan. Bounds in
the info: ``lower_bound_s`` (largest straight-line rest-to-rest time of any vehicle) and the
makespans after each stage.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from proxplan.planfile import Scenario
from proxplan.planner.sampling.ordering import lower_bound_makespan_s
from proxplan.planner.swarm.lacam import Lacam, SearchGaveUp
from proxplan.planner.swarm.lattice import build_lattice
from proxplan.planner.swarm.lockstep import lockstep_tracks
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.prioritized import PrioritizedFailed, prioritized_tracks
from proxplan.planner.swarm.problem import GROWTH_M, SwarmProblem, swarm_applicable, swarm_problem
from proxplan.planner.swarm.retime import improve, route_chain
from proxplan.planner.swarm.sync import SyncTable, segment_conflict
from proxplan.planner.swarm.tracks import GRID_DT_S, Track
from proxplan.planner.timing.paths import TimedPath
from proxplan.planner.timing.profile import LineMove, rest_to_rest

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
    max_restarts: int = 6  # re-orderings of the prioritised planning
    seed: int = 0


def straight_step_conflicts(problem: SwarmProblem) -> list[tuple[int, int]]:
    """Pairs (i, j) whose synchronised straight lines from start to goal conflict (exact test),
    and (i, i) for a line that leaves the static free space."""
    p0, p1 = problem.starts_m, problem.goals_m
    bad = [(i, i) for i in range(problem.n_agents) if not problem.segment_free(p0[i], p1[i])]
    mid = 0.5 * (p0 + p1)[:, :2]
    half = 0.5 * np.linalg.norm((p1 - p0)[:, :2], axis=1)
    radius = 2.0 * float(half.max(initial=0.0)) + problem.reach_xy_m
    for i, j in cKDTree(mid).query_pairs(radius, output_type="ndarray").tolist():
        rest = bool(np.allclose(p0[i], p1[i]) and np.allclose(p0[j], p1[j]))
        ko = problem.keepouts[(int(problem.type_index[i]), int(problem.type_index[j]))]
        if segment_conflict(ko, p0[j] - p0[i], p1[j] - p1[i], rest=rest, growth_m=GROWTH_M if rest else 0.0):
            bad.append((i, j))
    return bad


def _straight_tracks(problem: SwarmProblem) -> list[Track]:
    """Every vehicle straight to its goal in one synchronised step (common profile)."""
    lengths = np.linalg.norm(problem.goals_m - problem.starts_m, axis=1)
    movers = [a for a in range(problem.n_agents) if lengths[a] > 0.0]
    out = []
    profile = rest_to_rest(float(lengths.max(initial=0.0)), problem.common_limits(movers or [0]), GRID_DT_S)
    for a in range(problem.n_agents):
        mv = [(0, LineMove(problem.starts_m[a], problem.goals_m[a], profile))] if a in movers else []
        out.append(Track(a, int(problem.type_index[a]), problem.starts_m[a].copy(), mv))
    return out


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
    problem = swarm_problem(scenario)
    info: dict = {"lower_bound_s": lower_bound_makespan_s(scenario), "vehicles": problem.n_agents}
    conflicts = straight_step_conflicts(problem)
    configurations = None
    lattice = None
    tracks = None
    if not conflicts:
        tracks = _straight_tracks(problem)
        info["coordination"] = "one synchronised straight step"
    elif opts.prioritized:
        order = sorted(
            range(problem.n_agents), key=lambda a: (-float(np.linalg.norm(problem.goals_m[a] - problem.starts_m[a])), a)
        )
        horizon = int(round(max(4.0 * info["lower_bound_s"], info["lower_bound_s"] + 20.0) / GRID_DT_S))
        t1 = time.perf_counter()
        try:
            planned, counts = prioritized_tracks(
                problem,
                order,
                horizon_steps=horizon,
                max_restarts=opts.max_restarts,
                progress=progress,
                deadline=deadline,
            )
            tracks = [planned[a] for a in range(problem.n_agents)]
            info["coordination"] = f"prioritised continuous planning ({counts['orders_tried']} order(s))"
        except PrioritizedFailed as err:
            info["prioritized"] = f"gave up after {err.restarts} re-orderings: " + ", ".join(err.history)
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
