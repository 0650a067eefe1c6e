"""The planning order of a prioritised pass (:mod:`proxplan.planner.swarm.priority`): a vehicle whose start
another one's goal needs is planned first (it must leave before the other arrives); otherwise, and to break
cycles, the longer straight line first (it sets the makespan).
"""

from __future__ import annotations

import numpy as np

from proxplan.planner.swarm.problem import SwarmProblem
from proxplan.planner.ties import LENGTH_RESOLUTION_M, tie_key

__all__ = ["dependency_order"]


def dependency_order(problem: SwarmProblem) -> list[int]:
    """Planning order: a vehicle whose start another's goal needs goes before it (it has to leave
    first), ties and cycles broken by the longer straight line first (it sets the makespan)."""
    from scipy.spatial import cKDTree

    A = problem.n_agents
    length = np.linalg.norm(problem.goals_m - problem.starts_m, axis=1)
    key = {a: (-tie_key(float(length[a]), LENGTH_RESOLUTION_M), a) for a in range(A)}
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
