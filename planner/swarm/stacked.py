"""The stacked plan: each group of vehicle types on a level of its own (:mod:`proxplan.planner.swarm.levels`),
every level planned apart, joined by vertical steps at the start and at the end.

World frame, z up, m; times on the swarm grid (``GRID_DT_S``). Three phases, one after the other:

1. *down*: every vehicle from its start straight up or down to its level, in synchronous steps that
   pass the exact pair test (:func:`proxplan.planner.swarm.levels.transition_steps`, flown by
   :func:`proxplan.planner.swarm.lockstep.lockstep_tracks_at`: conflict-free by construction);
2. *levels*: from the end of the last vertical move, each level's vehicles fly that level's plan
   (``plan_level``, a plan of the subproblem of the level's vehicles between their starts and goals
   moved to the level; the caller's planner, conflict-free within the level). Two vehicles on
   different levels never conflict (the levels are as far apart as their types need, whatever the
   horizontal positions, moving or at rest), and every vehicle stays within its level's band (its
   height; the bottom level down to the floor, the top one up to the ceiling:
   :func:`~proxplan.planner.swarm.levels.level_bands_m`; checked: a level plan that leaves it is not used);
3. *up*: once every level's plan has ended, every vehicle from its goal on the level to its goal, as
   in 1.

So the tracks are conflict-free when each level's plan is. Re-timing
(:mod:`proxplan.planner.swarm.retime`) then moves every vehicle earlier where the others allow,
along its whole chain (start, the level, its route there, its goal).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from proxplan.planner.swarm.components import subproblem
from proxplan.planner.swarm.levels import Levels, levelled_endpoints, transition_steps
from proxplan.planner.swarm.lockstep import lockstep_tracks_at
from proxplan.planner.swarm.problem import SwarmProblem
from proxplan.planner.swarm.sync import SyncTable
from proxplan.planner.swarm.tracks import GRID_DT_S, GridTrack
from proxplan.planner.timing.profile import rest_to_rest

__all__ = [
    "StackedBound",
    "alone_steps",
    "StackedPlan",
    "level_subproblem",
    "stacked_bound",
    "stacked_tracks",
    "types_subproblem",
]

# a level plan's samples must stay this close to the level's height, m (whole-millimetre positions)
LEVEL_TOLERANCE_M = 1e-3


@dataclass(frozen=True)
class StackedPlan:
    """Tracks by agent index and the waypoint chain of each (start, level, route on it, goal)."""

    tracks: list[GridTrack]
    chains: list[np.ndarray]  # (m+1, 3) per agent, m
    down_steps: int  # synchronous vertical steps to the levels
    up_steps: int  # ... back to the goals
    level_makespans_s: list[float]  # each level's own plan, s


def _shifted(track: GridTrack, steps: int) -> list:
    return [(k0 + steps, mv) for k0, mv in track.moves]


def _chain(points: list[np.ndarray]) -> np.ndarray:
    out = [np.asarray(points[0], dtype=float)]
    for p in points[1:]:
        if float(np.linalg.norm(np.asarray(p) - out[-1])) > 1e-9:
            out.append(np.asarray(p, dtype=float))
    return np.array(out)


def types_subproblem(problem: SwarmProblem, agents: list[int]) -> SwarmProblem:
    """The subproblem of ``agents`` (:func:`~proxplan.planner.swarm.components.subproblem`) with only
    their types, numbered anew (the keep-outs of the types present): its reaches are those of the
    pairs that can meet on it, not of every type of the swarm."""
    sub = subproblem(problem, agents)
    types = sorted({int(t) for t in sub.type_index})
    new = {t: k for k, t in enumerate(types)}
    return replace(
        sub,
        type_index=np.array([new[int(t)] for t in sub.type_index], dtype=np.asarray(sub.type_index).dtype),
        vehicles=tuple(sub.vehicles[t] for t in types),
        keepouts={(new[a], new[b]): ko for (a, b), ko in sub.keepouts.items() if a in new and b in new},
    )


def level_subproblem(on_levels: SwarmProblem, agents: list[int], band_m: tuple[float, float]) -> SwarmProblem:
    """The subproblem of one level (:func:`types_subproblem` of ``agents`` of ``on_levels``, the problem
    with its starts and goals on their levels) with its free box cut to the level's band ``band_m``
    ((lowest, highest) height, m; :func:`~proxplan.planner.swarm.levels.level_bands_m`, give or take
    ``LEVEL_TOLERANCE_M``)."""
    sub = types_subproblem(on_levels, agents)
    lo, hi = sub.lo_m.copy(), sub.hi_m.copy()
    # the band's edges eased by the check's tolerance: a level's own height sits on an edge, where rounding
    # would put its starts outside the box
    lo[2] = max(float(lo[2]), band_m[0] - LEVEL_TOLERANCE_M)
    hi[2] = min(float(hi[2]), band_m[1] + LEVEL_TOLERANCE_M)
    return replace(sub, lo_m=lo, hi_m=hi)


def _vertical(
    problem: SwarmProblem, levels: Levels
) -> tuple[np.ndarray, list[tuple[int, ...]], list[tuple[int, ...]], list[GridTrack], list[GridTrack]] | None:
    """The vertical phases of the stacked plan (1 and 3 of the module): the points (starts, starts on
    the levels, goals on the levels, goals; (4 A, 3), m), the configurations of the steps down and up
    (indices into those points) and their lock-step tracks (each phase from its own step 0); None
    where the vertical steps cannot be found."""
    A = problem.n_agents
    lev_s, lev_g = levelled_endpoints(problem, levels)
    pos = np.vstack([problem.starts_m, lev_s, lev_g, problem.goals_m])
    sync = SyncTable(problem.keepouts, problem.type_index, np.round(pos * 1000.0).astype(np.int64))
    starts = tuple(range(A))
    down = transition_steps(sync.conflict, starts, tuple(range(A, 2 * A)))
    up = transition_steps(sync.conflict, tuple(range(2 * A, 3 * A)), tuple(range(3 * A, 4 * A)))
    sync.clear()  # its verdicts are not needed while the levels are planned (round 17A: held memory)
    if down is None or up is None:
        return None
    down_tracks = lockstep_tracks_at(problem, pos, [starts, *down])
    up_tracks = lockstep_tracks_at(problem, pos, [tuple(range(2 * A, 3 * A)), *up])
    return pos, down, up, down_tracks, up_tracks


@dataclass(frozen=True)
class StackedBound:
    """What bounds the makespan of every stacked plan of a problem on its levels, in grid steps
    (:func:`stacked_bound`): the steps down end at ``down_steps``; every level's plan starts there and
    the steps up start once the last has ended, L steps later; they end ``up_steps`` after that (their
    lock-step tracks' latest arrival, 0 where none moves). So the plan's makespan is down + L + up
    steps, and L is at least ``alone_steps``: a level's plan carries each of its vehicles from its start
    to its goal on the level, from rest to rest, so no earlier than its time-optimal rest-to-rest profile
    over that straight distance (:func:`~proxplan.planner.timing.profile.rest_to_rest`, in grid steps:
    nothing arrives earlier, as :func:`~proxplan.planner.swarm.makespan.shorten_makespan` counts
    ``alone``), and at least the makespan of any level already planned."""

    down_steps: int
    alone_steps: int
    up_steps: int

    def steps(self, planned_steps: int = 0) -> int:
        """The least makespan (grid steps) of a stacked plan one of whose levels' plans takes
        ``planned_steps``."""
        return self.down_steps + max(self.alone_steps, planned_steps) + self.up_steps


def alone_steps(problem: SwarmProblem) -> int:
    """The latest of ``problem``'s vehicles' time-optimal rest-to-rest flights straight from start to goal,
    in grid steps (``GRID_DT_S``): no plan of ``problem`` ends earlier (a level's bound, :class:`StackedBound`)."""
    return max(
        rest_to_rest(
            float(np.linalg.norm(problem.goals_m[a] - problem.starts_m[a])), problem.limits[a], GRID_DT_S
        ).steps
        for a in range(problem.n_agents)
    )


def stacked_bound(problem: SwarmProblem, levels: Levels) -> StackedBound | None:
    """The :class:`StackedBound` of every stacked plan of ``problem`` on ``levels`` (:func:`stacked_tracks`,
    whatever its levels' plans), or None where it makes none (no vertical steps). The vertical phases are
    those :func:`stacked_tracks` flies (the same function). Round 25A: the stacked plan made beside a
    prioritised plan only while it can be shorter."""
    vertical = _vertical(problem, levels)
    if vertical is None:
        return None
    _, _, _, down_tracks, up_tracks = vertical
    lev_s, lev_g = levelled_endpoints(problem, levels)
    alone = alone_steps(replace(problem, starts_m=lev_s, goals_m=lev_g))
    return StackedBound(
        down_steps=max(tr.arrival_step for tr in down_tracks),
        alone_steps=alone,
        up_steps=max(tr.arrival_step for tr in up_tracks),
    )


def stacked_tracks(
    problem: SwarmProblem,
    levels: Levels,
    plan_level: Callable[[SwarmProblem], list[GridTrack] | None],
) -> tuple[StackedPlan | None, str]:
    """The stacked plan of ``problem`` on ``levels`` (see module) and what it did; None (with why)
    where the vertical steps cannot be found, a level's plan gives up or is not made (``plan_level``
    None; no later level is planned) or leaves its level."""
    A = problem.n_agents
    lev_s, lev_g = levelled_endpoints(problem, levels)
    vertical = _vertical(problem, levels)
    if vertical is None:
        return None, "no conflict-free vertical steps to the levels"
    pos, down, up, down_tracks, up_tracks = vertical
    t_down = max(tr.arrival_step for tr in down_tracks)
    on_levels = replace(problem, starts_m=lev_s, goals_m=lev_g)
    level_tracks: dict[int, GridTrack] = {}
    makespans = []
    for j, (group, z) in enumerate(zip(levels.groups, levels.heights_m)):
        agents = [a for a in range(A) if int(problem.type_index[a]) in group]
        band = levels.band_m(j)
        got = plan_level(level_subproblem(on_levels, agents, band))
        if got is None:
            return None, f"the level at {z:.2f} m gave no plan"
        for k, tr in enumerate(got):
            zs = tr.positions_m[:, 2]
            if float(zs.min()) < band[0] - LEVEL_TOLERANCE_M or float(zs.max()) > band[1] + LEVEL_TOLERANCE_M:
                return None, f"the plan of the level at {z:.2f} m leaves its band {band[0]:.2f}-{band[1]:.2f} m"
            level_tracks[agents[k]] = tr
        makespans.append(max(tr.arrival_s for tr in got))
    t_up = t_down + max(tr.arrival_step for tr in level_tracks.values())
    tracks, chains = [], []
    for a in range(A):
        lv = level_tracks[a]
        moves = list(down_tracks[a].moves) + _shifted(lv, t_down) + _shifted(up_tracks[a], t_up)
        tracks.append(GridTrack(a, int(problem.type_index[a]), problem.starts_m[a], moves))
        route = lv.route_m if lv.route_m is not None else np.array([lev_s[a], *[mv.end_m for _, mv in lv.moves]])
        chains.append(_chain([problem.starts_m[a], lev_s[a], *route, lev_g[a], problem.goals_m[a]]))
    plan = StackedPlan(tracks, chains, len(down), len(up), makespans)
    return plan, f"{len(down)} + {len(up)} vertical steps"
