"""Frozen pairs and the unfreeze step (issue 37, round 19C): starts (or goals) that the swarm layer's
keep-outs allow at rest but not once either vehicle moves.

A pair's keep-out while either vehicle moves is its keep-out at rest grown by the tracking tube and the
millimetre growth (:mod:`proxplan.planner.swarm.keepout`). Two vehicles whose starts lie between the two
(clear at rest, in conflict moving) are *frozen*: every move of either starts inside the moving keep-out,
so no stage of the swarm layer (prioritised planning, LaCAM, the stacked plan) can ever move them; a search
would spend its whole budget first, so where the unfreeze step leaves one (:func:`frozen_unmoved`) the layer
gives up before it (random-3-64 of the bench's family: two triangles of large quads,
0.584 m apart horizontally at 0.716 m height difference, rest keep-out 0.565 m, moving 0.587 m). The
verifier is less strict at the plan's start: every vehicle's predicted tracking error is zero there, and
the tube it adds while moving is the scenario's ``tracking_margin_m`` (the swarm keep-outs add the bound on
the tracking error while moving, and at rest the bound while held, which is smaller: round 37Z).

The *unfreeze step* (:func:`plan_unfreeze`): before the swarm plan, a few vehicles (a greedy cover of the
frozen pairs) each fly one short straight rest-to-rest move horizontally away from their frozen partners,
to the nearest point (in ``UNFREEZE_STEP_M`` steps, up to the widest horizontal reach of any keep-out)
where they conflict with no other vehicle's start while moving, and whose move meets no other start
(exact relative-segment test, :func:`~proxplan.planner.swarm.sync.segment_conflict`; against a frozen
partner the keep-out at rest, which the pair starts clear of); every other vehicle
holds its start. The swarm layer then plans from the moved starts, and the unfreeze step is put in front of
its tracks. Only the departure of a frozen pair from inside its moving keep-out is outside the swarm
layer's model: the verifier judges it, as every plan. The same at the goals (last instead of first): the swarm layer
plans to the moved goals, and once every vehicle has arrived the movers fly back to their goals.
Movers within reach of each other (their moves could meet) are not unfrozen: :func:`plan_unfreeze` gives
None with the reason.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from proxplan.planfile import Scenario
from proxplan.planner.swarm.problem import SwarmProblem
from proxplan.planner.swarm.sync import segment_conflict
from proxplan.planner.timing.paths import TimedPath, time_parameterize

# the unfreeze distance is searched in steps of this much, m: positions are compared in whole millimetres
# (problem.GROWTH_M covers 2 mm); 5 mm keeps the move short without a fine search. Not watched on a layout
UNFREEZE_STEP_M = 0.005

__all__ = [
    "UNFREEZE_STEP_M",
    "Unfreeze",
    "apply_unfreezes",
    "frozen_pairs",
    "frozen_unmoved",
    "moved_points",
    "plan_unfreeze",
    "unfrozen_problem",
    "with_unfreeze",
]


@dataclass(frozen=True)
class Unfreeze:
    """Movers and where they go: ``points_m`` (A, 3) are the starts (or goals) with the movers' moved,
    m; ``movers`` the agents that move; ``partners`` per mover the agents it was frozen with."""

    at: str  # "starts" or "goals"
    movers: tuple[int, ...]
    partners: tuple[tuple[int, ...], ...]
    points_m: np.ndarray  # (A, 3) m

    def distances_m(self, original_m: np.ndarray) -> list[float]:
        return [float(np.linalg.norm(self.points_m[a] - original_m[a])) for a in self.movers]


def frozen_pairs(problem: SwarmProblem, points_m: np.ndarray) -> list[tuple[int, int]]:
    """Pairs (a < b) of vehicles resting at ``points_m`` (A, 3) clear of each other's keep-out at
    rest but inside it as soon as either moves (see module)."""
    p = np.asarray(points_m, dtype=float)
    out: list[tuple[int, int]] = []
    reach = problem.reach_xy_m
    for a in range(problem.n_agents - 1):
        rest_of = np.arange(a + 1, problem.n_agents)
        d = p[rest_of] - p[a]
        near = rest_of[np.hypot(d[:, 0], d[:, 1]) <= reach]
        for b in near.tolist():
            ko = problem.keepouts[(int(problem.type_index[a]), int(problem.type_index[b]))]
            rel = (p[b] - p[a])[None]
            if bool(ko.conflict(rel)[0]) and not bool(ko.conflict(rel, rest=True)[0]):
                out.append((a, b))
    return out


def frozen_unmoved(problem: SwarmProblem) -> list[str]:
    """Names (in ``problem``'s order) of the vehicles in a frozen pair at its starts or goals of which at least
    one vehicle is not pinned: the departure (or the later arrival) of that pair lies inside its moving
    keep-out, so no stage of the swarm layer can plan it (see module). Run after :func:`unfrozen_problem`: what
    the unfreeze step could not move. Two pinned (hovering) vehicles never move, so their pair is no obstacle."""
    out: set[int] = set()
    for points in (problem.starts_m, problem.goals_m):
        for a, b in frozen_pairs(problem, points):
            if not (problem.pinned[a] and problem.pinned[b]):
                out |= {a, b}
    return [problem.names[i] for i in sorted(out)]


def _cover(pairs: list[tuple[int, int]], pinned: np.ndarray) -> dict[int, list[int]] | None:
    """Greedy cover of ``pairs`` by movers (the vehicle in most uncovered pairs first, ties by index;
    never a pinned one): mover -> its frozen partners. None: a pair of two pinned vehicles."""
    left = list(pairs)
    out: dict[int, list[int]] = {}
    while left:
        count: dict[int, int] = {}
        for a, b in left:
            for v in (a, b):
                if not pinned[v]:
                    count[v] = count.get(v, 0) + 1
        if not count:
            return None
        mover = min(count, key=lambda v: (-count[v], v))
        out[mover] = [b if a == mover else a for a, b in pairs if mover in (a, b)]
        left = [(a, b) for a, b in left if mover not in (a, b)]
    return out


def plan_unfreeze(problem: SwarmProblem, at: str = "starts") -> tuple[Unfreeze | None, str]:
    """The unfreeze step of ``problem``'s frozen pairs at its ``at`` ("starts" or "goals"; see module)
    and what it did, or (None, why) where nothing is frozen or no unfreeze was found."""
    base = problem.starts_m if at == "starts" else problem.goals_m
    pairs = frozen_pairs(problem, base)
    if not pairs:
        return None, ""
    names = problem.names
    cover = _cover(pairs, problem.pinned)
    what = ", ".join(f"{names[a]}-{names[b]}" for a, b in pairs)
    if cover is None:
        return None, f"frozen pairs at the {at} ({what}), two hovering vehicles: no unfreeze"
    pts = np.array(base, dtype=float)
    reach = problem.reach_xy_m
    for mover, partners in cover.items():
        end = _unfreeze_end(problem, base, mover, partners, reach)
        if end is None:
            return None, f"frozen pairs at the {at} ({what}): no unfreeze move for {names[mover]} within {reach:.2f} m"
        pts[mover] = end
    movers = sorted(cover)
    for i, a in enumerate(movers):  # two movers whose moves could come within reach: not unfrozen together
        for b in movers[i + 1 :]:
            span = float(np.hypot(*(base[b, :2] - base[a, :2])))
            travel = float(np.linalg.norm(pts[a] - base[a]) + np.linalg.norm(pts[b] - base[b]))
            if span - travel <= reach:
                return None, f"frozen pairs at the {at} ({what}): movers {names[a]}, {names[b]} within reach"
    if frozen_pairs(problem, pts):
        return None, f"frozen pairs at the {at} ({what}): still frozen after the unfreeze"
    unfreeze = Unfreeze(at, tuple(movers), tuple(tuple(sorted(cover[a])) for a in movers), pts)
    moved = ", ".join(f"{names[a]} {100 * d:.1f} cm" for a, d in zip(movers, unfreeze.distances_m(base)))
    return unfreeze, f"frozen pairs at the {at} ({what}): moved out by {moved}"


def _unfreeze_end(
    problem: SwarmProblem, base: np.ndarray, mover: int, partners: list[int], reach_m: float
) -> np.ndarray | None:
    """The nearest point of ``mover``'s unfreeze (see module), whole millimetres, or None."""
    p = base[mover]
    u = np.zeros(2)
    for b in partners:
        v = p[:2] - base[b, :2]
        n = float(np.hypot(*v))
        if n > 0.0:
            u += v / n
    dirs = [u / float(np.hypot(*u))] if float(np.hypot(*u)) > 1e-9 else []
    dirs += [np.array([math.cos(k * math.pi / 4), math.sin(k * math.pi / 4)]) for k in range(8)]
    others = [b for b in range(problem.n_agents) if b != mover]
    frozen = set(partners)
    ta = int(problem.type_index[mover])
    for direction in dirs:
        for k in range(1, int(math.ceil(reach_m / UNFREEZE_STEP_M)) + 1):
            end = p.copy()
            end[:2] += k * UNFREEZE_STEP_M * direction
            end = np.round(end * 1000.0) / 1000.0
            if not problem.segment_free(p, end):
                break
            ok = True
            for b in others:
                ko = problem.keepouts[(ta, int(problem.type_index[b]))]
                d0, d1 = base[b] - p, base[b] - end
                # a frozen partner: the move never comes within its keep-out at rest (it leaves the moving one)
                met = segment_conflict(ko, d0, d1, rest=b in frozen)
                if bool(ko.conflict(d1[None])[0]) or met:
                    ok = False
                    break
            if ok:
                return end
    return None


def with_unfreeze(
    timed: dict[str, TimedPath], problem: SwarmProblem, unfreeze: Unfreeze, original_m: np.ndarray, grid_s: float
) -> tuple[dict[str, TimedPath], float]:
    """``timed`` (the swarm plan between the moved points) with the unfreeze step: before it (starts:
    every path shifted by the step's duration, the movers' moves first) or after it (goals: once the
    last vehicle has arrived, the movers fly to their goals); and the step's duration on the grid
    ``grid_s``, s. ``original_m``: the starts (or goals) before the unfreeze, (A, 3) m."""
    moves = {
        a: time_parameterize(
            np.array([unfreeze.points_m[a], original_m[a]])[:: 1 if unfreeze.at == "goals" else -1],
            None,
            problem.limits[a],
        )
        for a in unfreeze.movers
    }
    step = math.ceil(max(m.duration_s for m in moves.values()) / grid_s - 1e-9) * grid_s
    out: dict[str, TimedPath] = {}
    end = max(path.duration_s for path in timed.values())
    for a, name in enumerate(problem.names):
        path = timed[name]
        if unfreeze.at == "starts":
            first = moves.get(a)
            if first is None:  # holds its start during the step
                knots = np.concatenate([[0.0], path.knot_t_s + step])
                out[name] = TimedPath(
                    knots, np.vstack([path.knot_p_m[:1], path.knot_p_m]), [None] + list(path.segments)
                )
            else:
                knots = np.concatenate([first.knot_t_s, path.knot_t_s + step])
                pts = np.vstack([first.knot_p_m, path.knot_p_m])
                segs = list(first.segments) + [None] + list(path.segments)  # a hold to the step's end
                out[name] = TimedPath(knots, pts, segs)
        else:
            last = moves.get(a)
            if last is None:
                out[name] = path
            else:  # holds its moved goal until every vehicle has arrived, then flies to its goal
                knots = np.concatenate([path.knot_t_s, [end], end + last.knot_t_s[1:]])
                pts = np.vstack([path.knot_p_m, path.knot_p_m[-1:], last.knot_p_m[1:]])
                out[name] = TimedPath(knots, pts, list(path.segments) + [None] + list(last.segments))
    return out, step


def unfrozen_problem(problem: SwarmProblem) -> tuple[SwarmProblem, tuple[Unfreeze, ...], str]:
    """``problem`` with its starts and goals unfrozen (:func:`plan_unfreeze`), the unfreezes made and
    what was frozen and done ("" where nothing was frozen)."""
    unfreezes: list[Unfreeze] = []
    notes: list[str] = []
    for at in ("starts", "goals"):
        unfreeze, why = plan_unfreeze(problem, at)
        if why:
            notes.append(why)
        if unfreeze is not None:
            unfreezes.append(unfreeze)
    out = problem
    for unfreeze in unfreezes:
        if unfreeze.at == "starts":
            out = replace(out, starts_m=unfreeze.points_m)
        else:
            out = replace(out, goals_m=unfreeze.points_m)
    return out, tuple(unfreezes), "; ".join(notes)


def apply_unfreezes(
    timed: dict[str, TimedPath], problem: SwarmProblem, unfreezes: tuple[Unfreeze, ...], grid_s: float
) -> tuple[dict[str, TimedPath], float]:
    """:func:`with_unfreeze` of each unfreeze (``problem``: before the unfreeze) and the time the steps
    add, s."""
    added = 0.0
    for unfreeze in unfreezes:
        original = problem.starts_m if unfreeze.at == "starts" else problem.goals_m
        timed, step = with_unfreeze(timed, problem, unfreeze, original, grid_s)
        added += step
    return timed, added


def moved_points(scenario: Scenario, problem: SwarmProblem) -> bool:
    """Were ``problem``'s starts or goals moved by an unfreeze step (not the scenario's own)?"""
    vs = [scenario.vehicles[n] for n in problem.names]
    starts = np.array([v.start_m for v in vs], dtype=float)
    goals = np.array([v.goal_m if v.goal_m is not None else v.start_m for v in vs], dtype=float)
    return not (np.array_equal(starts, problem.starts_m) and np.array_equal(goals, problem.goals_m))
