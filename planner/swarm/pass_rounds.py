"""The placing rounds of the passing stage (:mod:`proxplan.planner.swarm.passes`, whose docstring says what
the stage does): vehicles in no conflict on their straight lines, each component at the earliest common
departure over its joint moves (:mod:`proxplan.planner.swarm.pass_moves`), late vehicles timed one by one;
rounds that make the vehicles hemming in a unit late, place it first or break it up, at most
:data:`MAX_PASS_ROUNDS`; then at most :data:`MAX_RAISES` raises of the latest vehicle's unit. The earliest
plan placed is kept.
"""

from __future__ import annotations

from functools import partial

import numpy as np

from proxplan.planner.swarm.hemmed import late_track, merged_group
from proxplan.planner.swarm.joint import JointMove, place_joint
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.pass_moves import conflict_components, fitted_below, has_move, move_options
from proxplan.planner.swarm.problem import SwarmProblem
from proxplan.planner.swarm.stage import Stage, own_routes
from proxplan.planner.swarm.stagger import Partial
from proxplan.planner.swarm.straight import own_straight_track
from proxplan.planner.swarm.tracks import GRID_DT_S, GridTrack
from proxplan.planner.swarm.yielding import YieldResult, blockers
from proxplan.planner.ties import LENGTH_RESOLUTION_M, tie_key

# a component no joint move can be placed for makes the vehicles hemming it in late (or is placed first,
# or its members become late), then all are placed again: at most this many times (a count, so the
# same problem gives the same plan); as the yielding stage's MAX_YIELD_ROUNDS, set on the named layouts
# (round 29S: 6 -> 24; corridor-64 by type places its plan at round 15 with swarm.hemmed's merged groups,
# 16 and 32 rounds give the same plan; grid, circle and pillar at 64 end within 6)
MAX_PASS_ROUNDS = 24
# then the component (or late vehicle) of the latest vehicle is placed first, at most this many times,
# while that shortens the plan (a count); chosen before any run, as MAX_PASS_ROUNDS
MAX_RAISES = 6

__all__ = ["MAX_PASS_ROUNDS", "MAX_RAISES", "makespan_step", "passing_rounds"]


def _place_component(
    occ: Occupancy, problem: SwarmProblem, options: list[JointMove], arrive_by: int | None
) -> list[GridTrack] | None:
    """The earliest-arriving placement over the joint moves ``options`` (their tracks), each conflict-free
    among its members as it is or staggered (:func:`fitted`), or None."""
    best: tuple[int, list[GridTrack]] | None = None
    for jm in options:
        if best is not None and jm.steps >= best[0]:
            break  # sorted by length: none later arrives earlier
        fit = fitted_below(problem, jm, None if best is None else best[0])
        if fit is None or isinstance(fit, Partial) or (best is not None and fit.steps >= best[0]):
            continue  # (place_joint could only arrive at best[0] or later)
        bound = arrive_by if best is None else best[0] - 1
        d = place_joint(occ, fit, arrive_by=bound)
        if d is None or (best is not None and d + fit.steps >= best[0]):
            continue
        best = (d + fit.steps, fit.tracks(problem, d))
    return None if best is None else best[1]


def passing_rounds(
    problem: SwarmProblem,
    horizon_steps: int,
    pairs: list[tuple[int, int]],
    through: set[int],
    arrive_by: int | None,
    pre: dict[int, GridTrack],
) -> YieldResult:
    """:func:`passing_stage` with the lines through an obstacle ``through`` late, but those with a track in
    ``pre``: fixed on it from the start."""
    comps = [
        c
        for c in conflict_components([(i, j) for i, j in pairs if i != j and not {i, j} & through])
        if any(not problem.pinned[a] for a in c)
    ]
    options = {c: move_options(problem, c) for c in comps}
    for c in comps:  # a component without any joint move is timed one by one from the start
        if not has_move(problem, c):
            options[c] = []
    late: set[int] = ({a for c in comps if not options[c] for a in c if not problem.pinned[a]} | through) - set(pre)
    comps = [c for c in comps if options[c]]
    in_comp = {a for c in comps for a in c}
    fixed = {a: own_straight_track(problem, a) for a in range(problem.n_agents) if a not in in_comp | late | set(pre)}
    occ = Occupancy(problem, list(fixed.values()) + list(pre.values()), horizon_steps)
    for a, tr in fixed.items():  # own-limit lines that meet on the grid (not in the synchronised test)
        met = occ.conflicting_agents(tr)
        hit = met - in_comp - late - set(pre)
        if hit:
            late |= {a} | {b for b in hit if not problem.pinned[b]}
        elif met & set(pre):  # in the way of a line timed first: late
            late.add(a)
    length = np.linalg.norm(problem.goals_m - problem.starts_m, axis=1)
    first: list[tuple[int, ...] | int] = []
    rounds = 0
    optional: set[int] = set()  # late only because they made a component wait
    stay: set[int] = set()  # such vehicles that could not be timed late: on their straight lines for good
    # the earliest plan so far: its tracks, late vehicles, vehicles in components, components, round
    kept: tuple[dict[int, GridTrack], set[int], set[int], int, int] | None = None
    while True:
        tracks, stuck, delayed = _place_all(problem, horizon_steps, comps, options, late, first, arrive_by, length, pre)
        if tracks is not None:
            if kept is None or makespan_step(tracks) < makespan_step(kept[0]):
                kept = (tracks, set(late), set(in_comp), len(comps), rounds)
            delayed = {b for b in delayed - late - stay if not problem.pinned[b]}
            if not delayed or rounds >= MAX_PASS_ROUNDS:
                break
            rounds += 1  # the vehicles that made a component wait are timed after the components
            late |= delayed
            optional |= delayed
            continue
        rounds += 1
        changed = False
        why = stuck[0][0]
        for unit, hem in stuck:  # every unit that could not be placed, in the order placed
            grown = {b for b in hem if not problem.pinned[b]} - in_comp - late - stay - set(pre)
            if grown:  # those hemming it in are timed late (as optional as it, where it is)
                late |= grown
                if unit in optional:
                    optional |= grown
            elif unit in optional:  # late only for a component's sake, and cannot be: on its line
                late.discard(unit)
                optional.discard(unit)
                stay.add(unit)
            elif isinstance(unit, tuple) and unit not in first:  # hemmed in by placed ones: placed first
                first.append(unit)
            elif isinstance(unit, tuple):  # placed first already: its members are timed one by one
                comps = [c for c in comps if c != unit]
                first = [c for c in first if c != unit]
                late |= {a for a in unit if not problem.pinned[a]}
                in_comp -= set(unit)
            elif unit not in first:  # a late vehicle hemmed in by placed ones only: placed first, once
                first.append(unit)
            elif (group := merged_group(problem, unit, hem, late, comps, partial(has_move, problem))) is not None:
                comps.append(group)  # placed first already, hemmed in by late ones: it and they pass together
                options[group] = move_options(problem, group)
                late -= set(group)
                optional -= set(group)
                in_comp |= set(group)
                first = [u for u in first if not (isinstance(u, int) and u in group)]
            else:  # placed first already and still hemmed in: no move of this stage frees it
                changed, why = False, unit
                break
            changed = True
        if rounds > MAX_PASS_ROUNDS or not changed:
            if kept is not None:
                break
            unit = why
            return YieldResult(
                None,
                tuple(sorted(in_comp | late | set(pre))),
                f"gave up after {rounds} round(s): {'component' if isinstance(unit, tuple) else 'vehicle'} "
                f"{_names(problem, unit)} has no joint move or timing arriving within "
                f"{(horizon_steps if arrive_by is None else arrive_by) * GRID_DT_S:.2f} s"
                + ("" if changed else ", hemmed in by placed vehicles only"),
            )
    for _ in range(MAX_RAISES):  # the unit of the latest vehicle placed first, while that shortens the plan
        latest = max(kept[0].values(), key=lambda tr: (tr.arrival_step, -tr.agent)).agent
        raised = next((c for c in comps if latest in c), latest if latest in late else None)
        if raised is None or (first and first[-1] == raised):
            break
        first = [u for u in first if u != raised] + [raised]
        rounds += 1
        tracks, *_ = _place_all(problem, horizon_steps, comps, options, late, first, arrive_by, length, pre)
        if tracks is None or makespan_step(tracks) >= makespan_step(kept[0]):
            break
        kept = (tracks, set(late), set(in_comp), len(comps), rounds)
    tracks, late, in_comp, n_comps, kept_round = kept
    ordered = [tracks[a] for a in range(problem.n_agents)]
    note = (
        f"straight lines of {problem.n_agents - len(in_comp | late | set(pre))} vehicles, {n_comps} group(s) passing "
        f"together ({len(in_comp)} vehicles), {len(late)} timed one by one"
        + (f", {len(pre)} lines through an obstacle timed first" if pre else "")
        + f" ({len(pairs)} conflicting pairs of the synchronised step, round {kept_round + 1} of {rounds + 1})"
    )
    return YieldResult(
        Stage(ordered, "prioritised", note, own_routes(problem, ordered)),
        tuple(sorted(in_comp | late | set(pre))),
        note,
    )


def makespan_step(tracks: dict[int, GridTrack]) -> int:
    """The latest arrival of ``tracks`` (by agent), grid steps."""
    return max(tr.arrival_step for tr in tracks.values())


def _names(problem: SwarmProblem, stuck: int | tuple[int, ...]) -> str:
    return "+".join(problem.names[a] for a in (stuck if isinstance(stuck, tuple) else (stuck,)))


def _place_all(
    problem: SwarmProblem,
    horizon_steps: int,
    comps: list[tuple[int, ...]],
    options: dict[tuple[int, ...], list[JointMove]],
    late: set[int],
    first: list[tuple[int, ...] | int],
    arrive_by: int | None,
    length: np.ndarray,
    pre: dict[int, GridTrack],
) -> tuple[dict[int, GridTrack] | None, list[tuple[tuple[int, ...] | int, set[int]]], set[int]]:
    """One placement (see module; ``first``: components and late vehicles placed before the others, the
    last raised first): (the tracks by agent, or None where some unit could not be placed; each such
    component or late agent with the agents hemming it in, in the order tried; the straight-flying
    vehicles that made a component wait, i.e. depart after step 0 or take a longer joint move than its
    shortest; ``pre``: tracks fixed from the start, lines through an obstacle timed first). A unit that cannot be placed is left out and the others placed, so one round finds them all."""
    members = {a for c in comps for a in c}
    fixed = {
        a: own_straight_track(problem, a)
        for a in range(problem.n_agents)
        if a not in members and a not in late and a not in pre
    }
    occ = Occupancy(problem, list(fixed.values()) + list(pre.values()), horizon_steps)
    tracks = dict(fixed) | pre
    units: list[tuple[int, ...] | int] = list(comps) + sorted(late)
    raised = [u for u in reversed(first) if u in units]
    rest_comps = sorted(
        (c for c in comps if c not in raised),
        key=lambda c: (-max(tie_key(float(length[a]), LENGTH_RESOLUTION_M) for a in c), c),
    )
    rest_late = sorted(
        (a for a in late if a not in raised), key=lambda a: (-tie_key(float(length[a]), LENGTH_RESOLUTION_M), a)
    )
    delayed: set[int] = set()  # straight-flying vehicles that made a component wait
    stuck: list[tuple[tuple[int, ...] | int, set[int]]] = []
    for u in raised + rest_comps + rest_late:
        if isinstance(u, tuple):
            got = _place_component(occ, problem, options[u], arrive_by)
            if got is None or max(tr.arrival_step for tr in got) > options[u][0].steps:
                hem: set[int] = set()
                for tr in options[u][0].tracks_at_zero(problem):
                    hem |= occ.conflicting_agents(tr) | blockers(occ, problem, tr.agent)
                if got is None:
                    stuck.append((u, hem - set(u)))
                    continue
                delayed |= hem & set(fixed)
        else:
            track = late_track(occ, problem, u, arrive_by)
            if track is None:
                stuck.append((u, blockers(occ, problem, u)))
                continue
            got = [track]
        for tr in got:
            tracks[tr.agent] = tr
            occ.put(tr)
    return (None if stuck else tracks), stuck, delayed
