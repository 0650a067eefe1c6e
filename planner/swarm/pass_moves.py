"""The joint moves of a component of conflicting vehicles, for the passing stage
(:mod:`proxplan.planner.swarm.passes`): which moves a component has (every moving member bulging aside at
once, or one on its line; resting members resting or stepping aside and back), which are conflict-free among
their members as they are or staggered (:mod:`proxplan.planner.swarm.stagger`), each asked once per problem
(``problem.static_memo``). Where they are placed among the other tracks is
:mod:`proxplan.planner.swarm.pass_rounds`.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from proxplan.planner.swarm.joint import JointMove, member_key, moving
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.problem import SwarmProblem
from proxplan.planner.swarm.stagger import Partial, staggered
from proxplan.planner.swarm.tracks import GRID_DT_S, GridTrack, Move
from proxplan.planner.swarm.yielding import left_of_line
from proxplan.planner.timing.arcs import ArcMove
from proxplan.planner.timing.profile import LineMove, rest_to_rest

# the bulge of each moving member of a joint move, in units of the widest keep-out's horizontal reach
# (problem.reach_xy_m): from half of it (two head-on partners each half aside clear the reach between
# them) to all of it (one partner on its line); chosen before any run (round 23S)
PASS_REACH_FACTORS = (0.5, 0.625, 0.75, 1.0)

__all__ = [
    "PASS_REACH_FACTORS",
    "conflict_components",
    "conflict_free",
    "fitted",
    "fitted_below",
    "has_move",
    "joint_moves",
    "move_options",
]


def conflict_components(pairs: list[tuple[int, int]]) -> list[tuple[int, ...]]:
    """The connected components (sorted agent tuples, in order of their smallest agent) of the graph
    whose edges are ``pairs`` (i != j), over the agents the pairs name."""
    agents = sorted({a for pair in pairs for a in pair})
    if not agents:
        return []
    index = {a: k for k, a in enumerate(agents)}
    i = [index[p[0]] for p in pairs]
    j = [index[p[1]] for p in pairs]
    graph = coo_matrix((np.ones(len(i)), (i, j)), shape=(len(agents), len(agents)))
    _, label = connected_components(graph, directed=False)
    groups: dict[int, list[int]] = {}
    for a, c in zip(agents, label):
        groups.setdefault(int(c), []).append(a)
    return sorted((tuple(g) for g in groups.values()), key=lambda g: g[0])


def _aside_legs(
    problem: SwarmProblem, a: int, away_m: np.ndarray, offset_steps: int, wait_steps: int
) -> tuple[tuple[tuple[int, Move], ...], np.ndarray] | None:
    """A resting agent ``a`` stepping ``away_m`` (3,), m, aside ``offset_steps`` grid steps after the
    common departure and back, rest to rest, waiting ``wait_steps`` aside (its legs, its route), or None
    where the point aside is not statically free."""
    s = problem.starts_m[a]
    c = s + away_m
    if not bool(problem.static_free(c[None])[0]):
        return None
    prof = rest_to_rest(float(np.linalg.norm(away_m)), problem.limits[a], GRID_DT_S)
    out, back = LineMove(s, c, prof), LineMove(c, s, prof)
    return ((offset_steps, out), (offset_steps + out.steps + wait_steps, back)), np.array([s, c, s])


def joint_moves(
    problem: SwarmProblem,
    members: tuple[int, ...],
    factors: tuple[float, ...] = PASS_REACH_FACTORS,
    *,
    checked: bool = True,
) -> list[JointMove]:
    """The joint moves of the component ``members`` (see module), statically free, in order of their
    length (grid steps), ties in the order tried; ``checked``: only those conflict-free among themselves
    (:func:`conflict_free`), else all (the caller checks those it uses: most are never tried)."""
    movers = [a for a in members if moving(problem, a)]
    lefts = {a: left_of_line(problem, a) for a in movers}
    left = {a: v for a, v in lefts.items() if v is not None}
    if not movers or len(left) < len(movers):
        return []
    resting = [a for a in members if a not in movers and not problem.pinned[a]]
    s, g = problem.starts_m, problem.goals_m
    line = {
        a: LineMove(s[a], g[a], rest_to_rest(float(np.linalg.norm(g[a] - s[a])), problem.limits[a], GRID_DT_S))
        for a in movers
    }
    arcs: dict[tuple[int, float], tuple[ArcMove, np.ndarray] | None] = {}

    def arc(a: int, signed_f: float) -> tuple[ArcMove, np.ndarray] | None:
        key = (a, signed_f)
        if key not in arcs:
            bulge = signed_f * problem.reach_xy_m * left[a]
            mv = ArcMove(s[a], g[a], bulge, problem.limits[a], GRID_DT_S)
            free = bool(problem.static_free(mv.positions()).all())
            arcs[key] = (mv, np.array([s[a], 0.5 * (s[a] + g[a]) + bulge, g[a]])) if free else None
        return arcs[key]

    out: list[JointMove] = []
    for f in factors:
        for sign, side in ((-1.0, "right"), (1.0, "left")):
            for keep in [None] + (movers if len(movers) > 1 else []):
                legs: dict[int, tuple[tuple[int, Move], ...]] = {}
                routes: dict[int, np.ndarray | None] = {}
                for a in movers:
                    got = (line[a], np.array([s[a], g[a]])) if a == keep else arc(a, sign * f)
                    if got is None:
                        break
                    legs[a], routes[a] = ((0, got[0]),), got[1]
                else:
                    label = f"{side} {f:g} reach" + ("" if keep is None else f", {problem.names[keep]} on its line")
                    out += _with_resting(problem, members, left, resting, legs, routes, sign * f, label)
    out.sort(key=lambda jm: jm.steps)  # stable: ties in the order tried
    return [jm for jm in out if conflict_free(problem, jm)] if checked else out


def _with_resting(
    problem: SwarmProblem,
    members: tuple[int, ...],
    left: dict[int, np.ndarray],
    resting: list[int],
    legs: dict[int, tuple[tuple[int, Move], ...]],
    routes: dict[int, np.ndarray | None],
    signed_f: float,
    label: str,
) -> list[JointMove]:
    """The joint moves of the movers' ``legs`` with the resting members resting, and (where there are
    any) stepping ``|signed_f|`` reach aside, away from the movers' bulge, and back: leaving at the
    common departure, at the latest step that has them aside at the movers' middle or half way between,
    and coming back at once, as the movers arrive or half way between; those conflict-free among
    themselves or not (checked by the caller)."""
    variants: list[tuple[dict, dict, str]] = [({}, {}, "")]
    movers = list(left)  # the moving members, each with the unit vector to the left of its line
    away = -signed_f * np.sum([left[a] for a in movers], axis=0) if resting else np.zeros(3)
    norm = float(np.linalg.norm(away))
    if norm > 1e-9:
        away = abs(signed_f) * problem.reach_xy_m * away / norm
        longest = max(k + mv.steps for a in movers for k, mv in legs[a])
        leg = rest_to_rest(float(np.linalg.norm(away)), problem.limits[resting[0]], GRID_DT_S).steps
        early = max(0, longest // 2 - leg)  # the latest step-out that is aside at the movers' middle
        for offset in sorted({0, early // 2, early}):
            latest_back = max(offset + leg, longest - leg)  # the return that ends as the movers arrive
            for back in sorted({offset + leg, (offset + leg + latest_back) // 2, latest_back}):
                got = {a: _aside_legs(problem, a, away, offset, back - offset - leg) for a in resting}
                if all(x is not None for x in got.values()):
                    variants.append(
                        (
                            {a: x[0] for a, x in got.items() if x is not None},
                            {a: x[1] for a, x in got.items() if x is not None},
                            f", resting ones aside at {offset}-{back} steps",
                        )
                    )
    return [
        JointMove(
            tuple(members),
            tuple(legs.get(a, extra_legs.get(a, ())) for a in members),
            tuple(routes.get(a, extra_routes.get(a)) for a in members),
            label + extra_label,
        )
        for extra_legs, extra_routes, extra_label in variants
    ]


def has_move(problem: SwarmProblem, members: tuple[int, ...]) -> bool:
    """Whether the component ``members`` has a joint move conflict-free among its members, as it is or
    staggered (:func:`fitted`)."""
    return any(fitted(problem, jm) is not None for jm in move_options(problem, members))


def conflict_free(problem: SwarmProblem, jm: JointMove) -> bool:
    """Whether the members' tracks of ``jm`` are conflict-free among themselves."""
    tracks = jm.tracks_at_zero(problem)
    occ = Occupancy(problem, tracks, jm.steps + 2)
    return all(not occ.conflicting_agents(tr) for tr in tracks)


def move_options(problem: SwarmProblem, members: tuple[int, ...]) -> list[JointMove]:
    """:func:`joint_moves` of the component ``members`` (unchecked), asked once per problem: a function
    of the problem alone, kept in ``problem.static_memo`` (the stage runs twice where goals were assigned,
    before and after prioritised planning; round 25S)."""
    return problem.static_memo.get(("joint moves", members), lambda: joint_moves(problem, members, checked=False))


def _free(problem: SwarmProblem, jm: JointMove) -> bool:
    """:func:`conflict_free` of ``jm``, asked once per problem (kept in ``problem.static_memo`` under its
    members and label, unique among a component's joint moves; 30 % of the stage's CPU on grid-256 by type),
    pair by pair (:func:`_pair_free`, until one conflicts)."""
    return problem.static_memo.get(("joint move free", jm.members, jm.label), lambda: _pairs_free(problem, jm))


@dataclass
class _Fitting:
    """What is known of a joint move's fitting (kept per problem, ``problem.static_memo``): ``done`` with
    its ``result`` (:func:`fitted`), or else the least arrival its staggering has shown (``lower``, grid
    steps after the common departure)."""

    done: bool = False
    result: JointMove | None = None
    lower: int = 0


def fitted(problem: SwarmProblem, jm: JointMove) -> JointMove | None:
    """``jm`` where it is conflict-free among its members (:func:`_free`), else, where every member moves
    (no resting member: those step aside in time with the movers), ``jm`` staggered
    (:func:`~proxplan.planner.swarm.stagger.staggered`); or None. Asked once per problem
    (``problem.static_memo``)."""
    got = fitted_below(problem, jm, None)
    assert not isinstance(got, Partial)  # only asked with a bound
    return got


def fitted_below(problem: SwarmProblem, jm: JointMove, below: int | None) -> JointMove | Partial | None:
    """:func:`fitted`, or, with ``below`` (a caller wanting only an arrival before that step), a
    :class:`~proxplan.planner.swarm.stagger.Partial` where the staggering shows, before it is finished, that
    the joint move arrives at that step or later (pillar-64 by type: 239 of 340 staggered joint moves were
    not wanted; round 28S)."""
    fit = problem.static_memo.get(("joint move fitted", jm.members, jm.label), _Fitting)
    if not fit.done:
        if below is not None and fit.lower >= below:
            return Partial(fit.lower)
        if _free(problem, jm):
            got: JointMove | Partial | None = jm
        elif all(moving(problem, a) for a in jm.members):
            got = staggered(problem, jm, below=below)
        else:
            got = None
        if isinstance(got, Partial):
            fit.lower = max(fit.lower, got.arrival_lower)
            return got
        fit.done, fit.result = True, got
    return fit.result


def _pairs_free(problem: SwarmProblem, jm: JointMove) -> bool:
    """:func:`conflict_free` of ``jm`` from its members' pairs: a track conflicts with a set of tracks where
    it does with one of them (``Occupancy.conflicting_agents`` tests each other track on its own, over the
    steps until the later of the two arrives), so the members are conflict-free among themselves where every
    pair is, each pair asked once per problem (round 26S: the joint moves of a component share most of their
    members' moves: a group of 8 on grid-256 by type has 72 joint moves, none conflict-free)."""
    tracks = jm.tracks_at_zero(problem)
    keys = [member_key(a, legs, route) for a, legs, route in zip(jm.members, jm.moves, jm.routes)]
    for x in range(len(tracks)):
        for y in range(x + 1, len(tracks)):
            key = ("pair free", keys[x], keys[y])
            if not problem.static_memo.get(key, partial(_pair_free, problem, tracks[x], tracks[y])):
                return False
    return True


def _pair_free(problem: SwarmProblem, ta: GridTrack, tb: GridTrack) -> bool:
    """Whether two tracks are conflict-free, each asked against the other (:func:`conflict_free`'s test)."""
    horizon = max(ta.arrival_step, tb.arrival_step) + 2
    return not Occupancy(problem, [tb], horizon).conflicting_agents(ta) and not Occupancy(
        problem, [ta], horizon
    ).conflicting_agents(tb)
