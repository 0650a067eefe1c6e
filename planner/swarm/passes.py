"""Conflicting vehicles pass together: each group of straight lines in conflict is flown as one joint
manoeuvre, every member bulging aside at once (issue 37 item 5; round 23S).

Where the synchronised straight step has conflicting pairs
(:func:`~proxplan.planner.swarm.straight.straight_step_conflicts`), the yielding stage
(:mod:`proxplan.planner.swarm.yielding`) times the vehicles of a pair one after the other: the first
is fixed before the second is timed, so two neighbours swapping slots head-on each need the whole
keep-out's reach aside, and a smooth detour (:class:`~proxplan.planner.timing.arcs.ArcMove`) that far
aside costs 1.39-1.41 B on grid-64 by type (B: the assignment's bound), against 1.11-1.18 B for each of
the two bulging half of it to its right (measured, round 23S). Here the vehicles of each connected group
of conflicting pairs (a *component*: a swap, a rotation of three, a line through a resting slot) are
timed together:

* the *joint moves* of a component (:func:`joint_moves`): every moving member on an arc bulging
  :data:`PASS_REACH_FACTORS` times the widest keep-out's horizontal reach aside, all to their right or
  all to their left (head-on partners then pass on opposite sides), or one member on its straight line
  and the others bulging; resting members rest, or step as far aside (away from the movers' bulge) and
  back, rest to rest, at a few offsets. All depart at one grid step; a joint move is used only where
  its members' tracks are conflict-free among themselves
  (:meth:`~proxplan.planner.swarm.occupancy.Occupancy.conflicting_agents`, asked when it is first
  tried), or made so by staggering its members' departures (:mod:`proxplan.planner.swarm.stagger`),
  and statically free (the joint move and its placement: :mod:`proxplan.planner.swarm.joint`); a component without any is timed one by one (below);
* every vehicle in no conflict flies its straight line at its own limits from t = 0; the components,
  longest line first, are placed at the earliest common departure the tracks fixed so far allow
  (:func:`place_joint`: holds at the start before it, at the goal after it, the flown samples,
  exactly as :func:`~proxplan.planner.swarm.arc_timing.time_arc` asks them), the earliest arrival over
  its joint moves kept; *late* vehicles are then timed one by one, as the yielding stage times its
  vehicles (:func:`~proxplan.planner.swarm.yielding.time_yielding`: waits, corners, arcs; else a wavefront
  route, :func:`~proxplan.planner.swarm.hemmed.late_track`, round 29S);
* rounds (at most :data:`MAX_PASS_ROUNDS`; every unit that cannot be placed is found in one round): the
  straight-flying vehicles hemming in a component that cannot be placed become late; a component
  hemmed in by placed ones only is placed first, and where it was already, its members become late; a
  placed plan whose components had to wait makes the straight-flying vehicles in their way late (as an
  option: one that then cannot be timed goes back on its line for good); a late vehicle hemmed in by
  placed ones only is placed first, once (pillar-64 by type: no plan before, 1.16 B with it; round
  24S); hemmed in again by late vehicles, it and they pass together where they have a joint move
  (:func:`~proxplan.planner.swarm.hemmed.merged_group`; round 29S: corridor-64 by type 1.90x -> 1.34x),
  else it ends the rounds (no move of the stage frees it; grid-256 spent 16 s of CPU for nothing before). Then, at most :data:`MAX_RAISES` times, the latest vehicle's component (or late
  vehicle) is placed first while that shortens the plan. The earliest plan placed is kept; with none
  the stage gives up (None) and says so.

A vehicle whose straight line leaves the static free space (through an obstacle) is in no component: it
is late from the start, timed round the obstacle through a corner beside its line's blocked stretch
(:func:`~proxplan.planner.swarm.yielding.around_obstacle`; round 24S: pillar-64 by type, 12 such lines,
1.83 B -> 1.16 B; timed late by the single-vehicle planner instead, corridor-64 and pillar-64 by type gave
up after 1.6 and 3.1 s of CPU, round 23S). The
yielding candidate does not try this stage inside the stacked plan's levels (the join re-times arcs
as corner chains: pillar-64 by type 1.83x -> 2.60x).

Every track is checked exactly against those placed before it (and the members of a component among
themselves), so the plan is conflict-free in the swarm layer's model; the verifier judges it as every plan.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from proxplan.planner.swarm.hemmed import late_track, merged_group
from proxplan.planner.swarm.joint import JointMove, member_key, moving, place_joint
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.problem import SwarmProblem
from proxplan.planner.swarm.stage import Stage, own_routes
from proxplan.planner.swarm.stagger import Partial, staggered
from proxplan.planner.swarm.straight import own_straight_track
from proxplan.planner.swarm.through_first import through_first
from proxplan.planner.swarm.tracks import GRID_DT_S, GridTrack, Move
from proxplan.planner.swarm.yielding import YieldResult, blockers, left_of_line
from proxplan.planner.timing.arcs import ArcMove
from proxplan.planner.timing.profile import LineMove, rest_to_rest

# the bulge of each moving member of a joint move, in units of the widest keep-out's horizontal reach
# (problem.reach_xy_m): from half of it (two head-on partners each half aside clear the reach between
# them) to all of it (one partner on its line); chosen before any run (round 23S)
PASS_REACH_FACTORS = (0.5, 0.625, 0.75, 1.0)
# a component no joint move can be placed for makes the vehicles hemming it in late (or is placed first,
# or its members become late), then all are placed again: at most this many times (a count, so the
# same problem gives the same plan); as the yielding stage's MAX_YIELD_ROUNDS, set on the named layouts
# (round 29S: 6 -> 24; corridor-64 by type places its plan at round 15 with swarm.hemmed's merged groups,
# 16 and 32 rounds give the same plan; grid, circle and pillar at 64 end within 6)
MAX_PASS_ROUNDS = 24
# then the component (or late vehicle) of the latest vehicle is placed first, at most this many times,
# while that shortens the plan (a count); chosen before any run, as MAX_PASS_ROUNDS
MAX_RAISES = 6

__all__ = [
    "MAX_PASS_ROUNDS",
    "MAX_RAISES",
    "PASS_REACH_FACTORS",
    "JointMove",
    "conflict_components",
    "conflict_free",
    "fitted",
    "joint_moves",
    "passing_stage",
    "place_joint",
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


def _has_move(problem: SwarmProblem, members: tuple[int, ...]) -> bool:
    """Whether the component ``members`` has a joint move conflict-free among its members, as it is or
    staggered (:func:`fitted`)."""
    return any(fitted(problem, jm) is not None for jm in _options(problem, members))


def conflict_free(problem: SwarmProblem, jm: JointMove) -> bool:
    """Whether the members' tracks of ``jm`` are conflict-free among themselves."""
    tracks = jm.tracks_at_zero(problem)
    occ = Occupancy(problem, tracks, jm.steps + 2)
    return all(not occ.conflicting_agents(tr) for tr in tracks)


def _options(problem: SwarmProblem, members: tuple[int, ...]) -> list[JointMove]:
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
    got = _fitted(problem, jm, None)
    assert not isinstance(got, Partial)  # only asked with a bound
    return got


def _fitted(problem: SwarmProblem, jm: JointMove, below: int | None) -> JointMove | Partial | None:
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


def _place_component(
    occ: Occupancy, problem: SwarmProblem, options: list[JointMove], arrive_by: int | None
) -> list[GridTrack] | None:
    """The earliest-arriving placement over the joint moves ``options`` (their tracks), each conflict-free
    among its members as it is or staggered (:func:`fitted`), or None."""
    best: tuple[int, list[GridTrack]] | None = None
    for jm in options:
        if best is not None and jm.steps >= best[0]:
            break  # sorted by length: none later arrives earlier
        fit = _fitted(problem, jm, None if best is None else best[0])
        if fit is None or isinstance(fit, Partial) or (best is not None and fit.steps >= best[0]):
            continue  # (place_joint could only arrive at best[0] or later)
        bound = arrive_by if best is None else best[0] - 1
        d = place_joint(occ, fit, arrive_by=bound)
        if d is None or (best is not None and d + fit.steps >= best[0]):
            continue
        best = (d + fit.steps, fit.tracks(problem, d))
    return None if best is None else best[1]


def passing_stage(
    problem: SwarmProblem,
    horizon_steps: int,
    pairs: list[tuple[int, int]],
    *,
    arrive_by: int | None = None,
) -> YieldResult:
    """The plan of the module (``horizon_steps``: grid steps a timing may use; ``pairs``: the straight
    step's conflicts; ``arrive_by``: only a plan whose every vehicle arrives by this step is of interest;
    None: any). ``YieldResult.yielders``: the vehicles in a component or late. Where lines through an
    obstacle meet one another's timings (:func:`~proxplan.planner.swarm.through_first.through_first`), the
    stage with them timed first, and the stage as before asked for a shorter plan than that one; the
    shorter kept."""
    if not pairs:
        return YieldResult(None, (), "no conflicting pair (the synchronised straight step is the plan)")
    through = {i for i, j in pairs if i == j and not problem.pinned[i]}  # lines through an obstacle: late
    pre = through_first(problem, horizon_steps, through, arrive_by)
    if pre is None:
        return _passing(problem, horizon_steps, pairs, through, arrive_by, {})
    first = _passing(problem, horizon_steps, pairs, through, arrive_by, pre)
    if first.stage is None:
        plain = _passing(problem, horizon_steps, pairs, through, arrive_by, {})
        return plain if plain.stage is not None else YieldResult(None, plain.yielders, f"{plain.note}; {first.note}")
    shorter = _makespan({tr.agent: tr for tr in first.stage.tracks}) - 1
    plain = _passing(
        problem, horizon_steps, pairs, through, shorter if arrive_by is None else min(arrive_by, shorter), {}
    )
    return plain if plain.stage is not None else first


def _passing(
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
    options = {c: _options(problem, c) for c in comps}
    for c in comps:  # a component without any joint move is timed one by one from the start
        if not _has_move(problem, c):
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
            if kept is None or _makespan(tracks) < _makespan(kept[0]):
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
            elif (group := merged_group(problem, unit, hem, late, comps, partial(_has_move, problem))) is not None:
                comps.append(group)  # placed first already, hemmed in by late ones: it and they pass together
                options[group] = _options(problem, group)
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
        if tracks is None or _makespan(tracks) >= _makespan(kept[0]):
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


def _makespan(tracks: dict[int, GridTrack]) -> int:
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
    rest_comps = sorted((c for c in comps if c not in raised), key=lambda c: (-max(float(length[a]) for a in c), c))
    rest_late = sorted((a for a in late if a not in raised), key=lambda a: (-float(length[a]), a))
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
