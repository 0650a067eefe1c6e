"""Groups of vehicles that never interact, planned apart (and fanned out on Dask).

Prioritised planning keeps every vehicle within its *region*: the horizontal box its wavefront
routes stay in (:func:`proxplan.planner.swarm.wave_grid.route_box`: start and goal grown by a margin, the
whole free box where a wall stands between them; the moves between their waypoints stay in its
hull) grown by the corner cut of a flight
through waypoints (:data:`proxplan.planner.timing.CORNER_DEVIATION_M`). Two vehicles whose regions
stay farther apart than the largest keep-out reach can never conflict, so the connected components
of the graph "regions within reach" (:func:`interaction_groups`) are planned independently, each as
its own :class:`~proxplan.planner.swarm.problem.SwarmProblem` (:func:`subproblem`), and their tracks
put together. The result is the same whether the groups run one after another or in parallel on
the project's Dask ``fanout`` (each group's planning depends on the group only), and the verifier
checks the whole plan as always.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from proxplan.planner.swarm.priority import prioritized_tracks
from proxplan.planner.swarm.priority_options import PrioritizedFailed, PriorityOptions, PriorityResult
from proxplan.planner.swarm.problem import SwarmProblem
from proxplan.planner.swarm.wave_grid import route_box
from proxplan.planner.timing import CORNER_DEVIATION_M

FANOUT_MIN_VEHICLES = 32  # a group is worth a Dask task from this size (a worker process costs seconds to start)


def interaction_groups(problem: SwarmProblem) -> list[list[int]]:
    """Connected components (agent index lists, each sorted, ordered by first agent) of the
    interaction graph (see module)."""
    A = problem.n_agents
    boxes = [route_box(problem, problem.starts_m[a], problem.goals_m[a]) for a in range(A)]
    lo = np.array([b[0] for b in boxes]) - CORNER_DEVIATION_M
    hi = np.array([b[1] for b in boxes]) + CORNER_DEVIATION_M
    pinned = problem.pinned
    lo[pinned] = problem.starts_m[pinned, :2]  # a hovering vehicle stays where it is
    hi[pinned] = problem.starts_m[pinned, :2]
    gap = np.maximum(0.0, np.maximum(lo[:, None, :] - hi[None, :, :], lo[None, :, :] - hi[:, None, :]))
    near = np.linalg.norm(gap, axis=2) <= problem.reach_xy_m
    i, j = np.nonzero(near)
    graph = coo_matrix((np.ones(i.size), (i, j)), shape=(A, A))
    n, label = connected_components(graph, directed=False)
    groups = [np.flatnonzero(label == c).tolist() for c in range(n)]
    return sorted(groups, key=lambda g: g[0])


def subproblem(problem: SwarmProblem, agents: list[int]) -> SwarmProblem:
    """The problem of ``agents`` alone (agent k of it is ``agents[k]`` of ``problem``)."""
    idx = np.asarray(agents, dtype=np.int64)
    return replace(
        problem,
        names=tuple(problem.names[a] for a in agents),
        type_index=problem.type_index[idx],
        limits=tuple(problem.limits[a] for a in agents),
        starts_m=problem.starts_m[idx],
        goals_m=problem.goals_m[idx],
        pinned=problem.pinned[idx],
    )


def _plan_group(job: tuple) -> tuple[str, object]:
    """One group's prioritised planning (a fan-out task: depends on its job only)."""
    sub, order_of, options, horizon = job
    try:
        return "ok", prioritized_tracks(sub, order_of(sub), options, horizon_steps=horizon)
    except PrioritizedFailed as err:
        return "failed", err


def plan_groups(
    problem: SwarmProblem,
    groups: list[list[int]],
    order_of: Callable[[SwarmProblem], list[int]],
    options: PriorityOptions,
    *,
    horizon_steps: int,
    workers: int,
    fanout_min_vehicles: int = FANOUT_MIN_VEHICLES,
    progress: Callable[[str, float], None] | None = None,
    deadline: float | None = None,
) -> PriorityResult:
    """Prioritised planning of every group (``order_of(group problem)`` gives each its order), put
    together with the agents' own indices; :class:`PrioritizedFailed` (of a global agent) when a
    group gives up. A budget of plannings (``options.max_plannings``) is shared by the groups in
    proportion to their sizes. Groups of at least ``fanout_min_vehicles`` run as Dask tasks when ``workers``
    > 1 and there are two of them or more; the rest, and everything when ``workers`` <= 1, here."""
    from proxplan.fanout import fan_out

    subs = [subproblem(problem, g) if len(groups) > 1 else problem for g in groups]
    n = sum(len(g) for g in groups)
    per_group = [
        options
        if options.max_plannings is None
        else replace(options, max_plannings=math.ceil(options.max_plannings * len(g) / n))
        for g in groups
    ]
    big = [k for k, g in enumerate(groups) if len(g) >= fanout_min_vehicles]
    remote = big if workers > 1 and len(big) >= 2 else []
    outcomes: dict[int, tuple[str, object]] = {}
    if remote:
        jobs = [(subs[k], order_of, per_group[k], horizon_steps) for k in remote]
        for k, out in zip(remote, fan_out(_plan_group, jobs, n_workers=min(workers, len(remote))).results):
            outcomes[k] = out
    for k in range(len(groups)):
        if k not in outcomes:
            sub = subs[k]
            try:
                outcomes[k] = (
                    "ok",
                    prioritized_tracks(
                        sub,
                        order_of(sub),
                        per_group[k],
                        horizon_steps=horizon_steps,
                        progress=progress,
                        deadline=deadline,
                    ),
                )
            except PrioritizedFailed as err:
                outcomes[k] = ("failed", err)
    merged = PriorityResult({}, 0, 0)
    for k, g in enumerate(groups):
        status, out = outcomes[k]
        if status == "failed":
            assert isinstance(out, PrioritizedFailed)
            raise PrioritizedFailed(g[out.agent], out.repairs, out.history, planned=out.planned, charged=out.charged)
        assert isinstance(out, PriorityResult)
        for a_local, tr in out.tracks.items():
            merged.tracks[g[a_local]] = tr.relabel(g[a_local]) if len(groups) > 1 else tr
        merged.planned += out.planned
        merged.repairs += out.repairs
        merged.against_order += out.against_order
        merged.history += out.history
    return merged


__all__ = ["FANOUT_MIN_VEHICLES", "interaction_groups", "plan_groups", "subproblem"]
