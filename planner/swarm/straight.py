"""Straight lines first: every vehicle straight to its goal, all at once.

Every vehicle flying its straight line in one synchronised step (one common rest-to-rest profile,
the longest line's at the movers' common limits) moves each pair's relative position along a
straight segment, checked exactly (:func:`proxplan.planner.swarm.sync.segment_conflict`). When all
pairs pass, that is the plan (the CAPT case of interchangeable goals).

Where some pairs conflict, :func:`kept_straight_lines` keeps the straight line, each at its
vehicle's own limits from t = 0, of every vehicle in no conflict (checked on the grid samples
against all the other straight lines, :meth:`~proxplan.planner.swarm.occupancy.Occupancy.conflicting_agents`),
and prioritised planning plans only the others around them (repairing kept lines that are in the
way).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from proxplan.planner.swarm.problem import GROWTH_M, SwarmProblem
from proxplan.planner.swarm.sync import segment_conflict
from proxplan.planner.swarm.tracks import GRID_DT_S, GridTrack
from proxplan.planner.timing.profile import LineMove, rest_to_rest


def _pairs(problem: SwarmProblem) -> np.ndarray:
    p0, p1 = problem.starts_m, problem.goals_m
    mid = 0.5 * (p0 + p1)[:, :2]
    half = 0.5 * np.linalg.norm((p1 - p0)[:, :2], axis=1)
    radius = 2.0 * float(half.max(initial=0.0)) + problem.reach_xy_m
    return cKDTree(mid).query_pairs(radius, output_type="ndarray")


def straight_step_conflicts(problem: SwarmProblem) -> list[tuple[int, int]]:
    """Pairs (i, j) whose synchronised straight lines from start to goal conflict (exact test),
    and (i, i) for a line that leaves the static free space."""
    p0, p1 = problem.starts_m, problem.goals_m
    bad = [(i, i) for i in range(problem.n_agents) if not problem.segment_free(p0[i], p1[i])]
    for i, j in _pairs(problem).tolist():
        rest = bool(np.allclose(p0[i], p1[i]) and np.allclose(p0[j], p1[j]))
        ko = problem.keepouts[(int(problem.type_index[i]), int(problem.type_index[j]))]
        if segment_conflict(ko, p0[j] - p0[i], p1[j] - p1[i], rest=rest, growth_m=GROWTH_M if rest else 0.0):
            bad.append((i, j))
    return bad


def straight_tracks(problem: SwarmProblem, agents: list[int]) -> dict[int, GridTrack]:
    """``agents`` straight to their goals in one synchronised step (a common profile)."""
    lengths = np.linalg.norm(problem.goals_m - problem.starts_m, axis=1)
    movers = [a for a in agents if lengths[a] > 0.0]
    out: dict[int, GridTrack] = {}
    if not agents:
        return out
    profile = rest_to_rest(
        float(max((lengths[a] for a in movers), default=0.0)), problem.common_limits(movers or agents), GRID_DT_S
    )
    for a in agents:
        mv = [(0, LineMove(problem.starts_m[a], problem.goals_m[a], profile))] if a in movers else []
        out[a] = GridTrack(a, int(problem.type_index[a]), problem.starts_m[a].copy(), mv)
    return out


def own_straight_track(problem: SwarmProblem, a: int) -> GridTrack:
    """Agent ``a`` straight to its goal at its own limits from t = 0, rest to rest (resting where it has
    no line or is pinned)."""
    s, g = problem.starts_m[a], problem.goals_m[a]
    length = float(np.linalg.norm(g - s))
    moves = (
        []
        if length <= 0.0 or problem.pinned[a]
        else [(0, LineMove(s, g, rest_to_rest(length, problem.limits[a], GRID_DT_S)))]
    )
    return GridTrack(a, int(problem.type_index[a]), s.copy(), moves)


def kept_straight_lines(problem: SwarmProblem, horizon_steps: int) -> tuple[dict[int, GridTrack], set[int]]:
    """(the straight tracks of the vehicles in no conflict, each at its own limits from t = 0; the
    vehicles in conflict): every moving vehicle's straight line against all the others' (see module)."""
    from proxplan.planner.swarm.occupancy import Occupancy

    tracks = {a: own_straight_track(problem, a) for a in range(problem.n_agents)}
    occ = Occupancy(problem, list(tracks.values()), horizon_steps)
    conflicted: set[int] = {
        a for a in range(problem.n_agents) if not problem.segment_free(problem.starts_m[a], problem.goals_m[a])
    }
    for a, tr in tracks.items():
        hit = occ.conflicting_agents(tr)
        if hit:
            conflicted |= hit | {a}
    conflicted -= {a for a in range(problem.n_agents) if problem.pinned[a]}
    return {a: tr for a, tr in tracks.items() if a not in conflicted}, conflicted
