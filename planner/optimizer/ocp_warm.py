"""Warm-start repair for the trajectory problem: move warm paths out of jets they cross.

A warm path that runs straight through a source's jet sits where the authority constraint is
violated and, on the jet's axis, where the wrench has no lateral gradient (a saddle of the
symmetric field): IPOPT then spends hundreds of iterations, with restoration phases, breaking the
symmetry. Displacing the warm nodes horizontally away from the source's axis until the predicted
usage is under the limit gives IPOPT a start on the right side of the jet. It does not change the
problem, only where IPOPT starts (world frame, m).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from proxplan.physics import normalised_motor_map
from proxplan.planner.optimizer.ocp_problem import OcpAgent, OcpProblem

STEP_M = 0.05  # lateral displacement per repair round, m
MAX_SHIFT_M = 1.5  # largest displacement of any node, m
SMOOTHING_NODES = 2.0  # Gaussian width of the displacement bump, nodes


def _usage_at_nodes(
    problem: OcpProblem, warm: dict[str, np.ndarray], target: OcpAgent
) -> tuple[np.ndarray, np.ndarray]:
    """(usage (n+1,), index of the strongest source per node (n+1,)) of ``target`` on the warm
    paths, from the problem's wrench functions (offset p_target - p_source -> F_z, tau_x, tau_y)."""
    a_map, up, down = normalised_motor_map(target.vehicle)
    n1 = warm[target.name].shape[0]
    delta = np.zeros((4, n1))
    strongest = np.full(n1, -1)
    best = np.zeros(n1)
    for idx, source in enumerate(problem.agents):
        fn = problem.wrench_functions.get((source.name, target.name))
        if fn is None or source.name == target.name:
            continue
        offsets = warm[target.name] - warm[source.name]
        below = offsets[:, 2] < 0.0
        wrench = np.zeros((3, n1))
        if below.any():
            wrench[:, below] = np.asarray(fn.map(int(below.sum()))(offsets[below].T)).reshape(3, -1)
        part = a_map @ wrench
        delta += part
        alone = np.maximum((part / up[:, None]).max(axis=0), (-part / down[:, None]).max(axis=0))
        stronger = alone > best
        best[stronger], strongest[stronger] = alone[stronger], idx
    usage = np.maximum((delta / up[:, None]).max(axis=0), (-delta / down[:, None]).max(axis=0))
    return usage, strongest


def _away_directions(path: np.ndarray, sources: np.ndarray) -> np.ndarray:
    """Horizontal unit vectors (n+1, 3) from each source position (n+1, 3) to the path; on a source's
    axis, the left normal of the path's horizontal direction (a fixed side, so neighbours agree)."""
    rel = path - sources
    rel[:, 2] = 0.0
    norm = np.linalg.norm(rel, axis=1)
    heading = np.gradient(path, axis=0)
    heading[:, 2] = 0.0
    left = np.column_stack([-heading[:, 1], heading[:, 0], np.zeros(len(path))])
    left_norm = np.linalg.norm(left, axis=1)
    left = np.where(left_norm[:, None] > 1e-9, left / np.maximum(left_norm, 1e-9)[:, None], [0.0, 1.0, 0.0])
    return np.where(norm[:, None] > 1e-3, rel / np.maximum(norm, 1e-9)[:, None], left)


def repair_warm_start(problem: OcpProblem) -> tuple[OcpProblem, int]:
    """The problem with every moving vehicle's warm path pushed out of the jets where it breaks
    ``authority_fraction`` (end nodes stay); and how many nodes were moved."""
    if not problem.wrench_functions:
        return problem, 0
    n1 = problem.n_intervals + 1
    warm = {
        a.name: (np.asarray(a.warm_position_m, float).copy() if a.moving and a.warm_position_m is not None
                 else np.asarray(a.fixed_path_m, float)[:n1].copy() if a.fixed_path_m is not None
                 else np.tile(np.asarray(a.start_m, float), (n1, 1)))
        for a in problem.agents
    }  # fmt: skip
    limit = problem.authority_fraction * problem.authority_margin
    k = np.arange(n1)
    moved_nodes: set[tuple[str, int]] = set()
    for target in problem.agents:
        if not target.moving or target.warm_position_m is None:
            continue
        shift = np.zeros(n1)
        for _ in range(int(MAX_SHIFT_M / STEP_M)):
            usage, strongest = _usage_at_nodes(problem, warm, target)
            bad = np.flatnonzero((usage > limit) & (strongest >= 0) & (k > 0) & (k < n1 - 1))
            if bad.size == 0:
                break
            sources = np.array([warm[problem.agents[s].name][i] if s >= 0 else warm[target.name][i]
                                for i, s in enumerate(strongest)])  # fmt: skip
            away = _away_directions(warm[target.name], sources)
            bump = np.exp(-0.5 * ((k[:, None] - bad[None, :]) / SMOOTHING_NODES) ** 2).max(axis=1)
            bump[[0, n1 - 1]] = 0.0
            warm[target.name] += STEP_M * bump[:, None] * away
            shift += STEP_M * bump
            moved_nodes.update((target.name, int(i)) for i in bad)
            if shift.max() >= MAX_SHIFT_M:
                break
    if not moved_nodes:
        return problem, 0
    agents = tuple(
        dataclasses.replace(a, warm_position_m=warm[a.name]) if a.moving and a.warm_position_m is not None else a
        for a in problem.agents
    )
    return dataclasses.replace(problem, agents=agents), len(moved_nodes)
