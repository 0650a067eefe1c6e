"""Straight lines with yielding vehicles: CAPT's synchronised straight lines where they hold, a
detour for the vehicles of the conflicting pairs (issue 37 item 5).

Where the straight step has conflicting pairs (:func:`~proxplan.planner.swarm.straight.straight_step_conflicts`),
who gives way is decided *before* any planning, two ways (:func:`~proxplan.planner.swarm.give_way.yielding_candidate`
keeps the shorter, after the vehicles passing together of :mod:`~proxplan.planner.swarm.passes`):

* *the shorter line yields*: in each pair not yet covered, the vehicle with the shorter straight line
  (its detour the cheaper; ties: more conflicts, then the lower index), a greedy vertex cover;
* *keep right*: every vehicle in a pair yields, on a corner to its right (seen from above, heading
  to its goal; head-on partners then pass on opposite sides), except a vehicle whose line is longer
  than each of its partners', which may keep its line; the yielding vehicles not timed yet are
  predicted on their smallest bulge to the right (their line for those that may keep it), and the
  predictions are dropped where they alone hem a vehicle in.

Every other vehicle flies its straight line at its own limits from t = 0 (own-limit lines that meet
on the grid samples, :meth:`~proxplan.planner.swarm.occupancy.Occupancy.conflicting_agents`, yield
too). Each yielding vehicle, longest line first, is timed against the tracks fixed so far
(:func:`~proxplan.planner.swarm.chain.time_chain`: waits at any waypoint, moves straight or flown
*through* the corner, exact against the tracks) along the best of its straight line and the chains
start -> corner -> goal, the corner beside the line's middle :data:`ASIDE_REACH_FACTORS` times the
widest keep-out's horizontal reach aside (for a line through an obstacle, instead, the chains round it:
:func:`around_obstacle`), and of the smooth arcs bulging :data:`ARC_REACH_FACTORS` times
that reach aside (:func:`~proxplan.planner.swarm.arc_timing.time_arc`: a delayed start, then one
flight timed along the curve without slowing at a corner; round 21S: circle-64 1.42x -> 1.24x). Where one cannot be timed, the vehicles hemming it in
(meeting its line, or it resting at its start or goal) yield too, or where they all yield already it
is timed first, and all are placed again, at most :data:`MAX_YIELD_ROUNDS` times; then the stage
gives up (None) and says so. Every track is checked exactly against those timed before it, so the
plan is conflict-free in the swarm layer's model; the verifier judges it as every plan.

Measured on grid-64 and circle-64 by type (docs/planner.md, stop 58 round 20S): no relative delay
of the two straight lines resolves 12 of grid's 19 conflicting pairs nor any of circle's 43 within
1.3 B (head-on swaps and rotations of three), so someone must leave its line.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial

import numpy as np

from proxplan.planner.swarm.arc_timing import time_arc
from proxplan.planner.swarm.chain import time_chain
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.problem import SwarmProblem
from proxplan.planner.swarm.stage import Stage, own_routes
from proxplan.planner.swarm.straight import own_straight_track, straight_step_conflicts
from proxplan.planner.swarm.tracks import GRID_DT_S, GridTrack
from proxplan.planner.ties import LENGTH_RESOLUTION_M, tie_key
from proxplan.planner.timing import CORNER_DEVIATION_M
from proxplan.planner.timing.profile import RunMove

# how far beside the middle of its line a yielding vehicle's corner lies, in units of the widest
# keep-out's horizontal reach (problem.reach_xy_m): from half of it (the other's column just cleared
# by a flight through the corner, whose rounding cuts it) to twice it; chosen before any run (a
# quarter of it as well changed nothing on circle-64 by type, round 20S)
ASIDE_REACH_FACTORS = (0.5, 0.75, 1.0, 1.25, 1.5, 2.0)
# a yielding vehicle that cannot be timed makes the vehicles hemming it in yield too (or, where they
# all yield already, is timed first among the yielding), then all are placed again: at most this many
# times (a count, so the same problem gives the same plan); set on the named layouts (round 20S):
# circle 16-128 need 1 round, grid-16 keeping right 4, grid 32-128 found none within 9
MAX_YIELD_ROUNDS = 4
# the bulges of a yielding vehicle's smooth detours (swarm.arc_timing, timing.arcs), in units of the
# widest keep-out's horizontal reach, tried beside its corners: from a quarter of it to the widest
# corner's rounded offset; chosen before any run (round 21S)
ARC_REACH_FACTORS = (0.25, 0.5, 0.75, 1.0, 1.25)
# a straight line that leaves the static free space (through an obstacle) is flown round it instead, through
# a corner beside the middle of its blocked stretch: the nearest corner on each side whose two legs are
# statically free, searched in steps of half the widest keep-out's horizontal reach (the finest step of
# ASIDE_REACH_FACTORS), at most this many steps aside (a count: 16 half-reaches, 2.4-3.2 m here, beyond
# the widest obstacle of the named layouts; round 24S)
AROUND_STEPS = 16
AROUND_STEP_REACH = 0.5  # the step of that search, in units of the widest keep-out's horizontal reach
BLOCKED_SAMPLE_M = 0.02  # the line is sampled this often to find its blocked stretch, m (as segment_free)
# ... and flown round it on a smooth arc as well (round 29S: corridor-64 by type, the line setting B through
# the wall flown alone through one corner 1.57 B, through the shortest path's two corners 1.63 B, on the
# smallest free arc 1.19 B): per side the smallest bulge, in the same steps as the corners, whose curve is
# statically free (the curve sampled every BLOCKED_SAMPLE_M of its chord, finer than the grid's samples)
ROUND_ARCS = True

__all__ = [
    "ARC_REACH_FACTORS",
    "ASIDE_REACH_FACTORS",
    "MAX_YIELD_ROUNDS",
    "AROUND_STEPS",
    "YieldResult",
    "around_obstacle",
    "round_arc_bulges",
    "blockers",
    "choose_yielders",
    "left_of_line",
    "time_yielding",
    "yielding_stage",
]


@dataclass(frozen=True)
class YieldResult:
    """What :func:`yielding_stage` did: the stage (None: it gave up) and a one-line account."""

    stage: Stage | None
    yielders: tuple[int, ...]
    note: str


def _line_lengths_m(problem: SwarmProblem) -> np.ndarray:
    return np.linalg.norm(problem.goals_m - problem.starts_m, axis=1)


def choose_yielders(problem: SwarmProblem, pairs: list[tuple[int, int]]) -> set[int]:
    """A greedy vertex cover of the conflicting ``pairs`` (i != j): in each pair not covered yet,
    the vehicle with the shorter straight line, ties by more conflicts, then the lower index."""
    length = _line_lengths_m(problem)
    degree: dict[int, int] = {}
    for i, j in pairs:
        degree[i] = degree.get(i, 0) + 1
        degree[j] = degree.get(j, 0) + 1
    out: set[int] = set()
    for i, j in pairs:
        if i in out or j in out or problem.pinned[i] and problem.pinned[j]:
            continue
        cands = [a for a in (i, j) if not problem.pinned[a]]
        out.add(min(cands, key=lambda a: (tie_key(float(length[a]), LENGTH_RESOLUTION_M), -degree[a], a)))
    return out


def left_of_line(problem: SwarmProblem, a: int) -> np.ndarray | None:
    """(3,) the horizontal unit vector to the left of agent ``a``'s straight line (seen from above, heading to
    its goal; its right is minus it), or None where the line has no horizontal part."""
    d = problem.goals_m[a] - problem.starts_m[a]
    horizontal = np.array([-d[1], d[0], 0.0])
    norm = float(np.linalg.norm(horizontal))
    return None if norm <= 1e-9 else horizontal / norm


def around_obstacle(problem: SwarmProblem, a: int) -> list[np.ndarray]:
    """The chains start -> corner -> goal of agent ``a`` round the obstacle its straight line passes
    through: per side (its left, then its right), the corner nearest the middle of the line's blocked
    stretch, :data:`AROUND_STEP_REACH` reach apart, at most :data:`AROUND_STEPS` steps aside, whose two legs
    are statically free ([] where its line is free, or no corner within the search is)."""
    s, g = problem.starts_m[a], problem.goals_m[a]
    if problem.segment_free(s, g):
        return []
    left = left_of_line(problem, a)
    side = left if left is not None else np.array([1.0, 0.0, 0.0])  # no horizontal line: x aside
    n = max(2, int(np.ceil(float(np.linalg.norm(g - s)) / BLOCKED_SAMPLE_M)) + 1)
    points = s[None] + np.linspace(0.0, 1.0, n)[:, None] * (g - s)[None]
    blocked = np.flatnonzero(~problem.static_free(points))
    if not blocked.size:
        return []
    middle = points[(int(blocked[0]) + int(blocked[-1])) // 2]
    out = []
    for sign in (1.0, -1.0):
        for k in range(1, AROUND_STEPS + 1):
            corner = middle + sign * k * AROUND_STEP_REACH * problem.reach_xy_m * side
            if (
                problem.static_free(corner[None])[0]
                and problem.segment_free(s, corner)
                and problem.segment_free(corner, g)
            ):
                out.append(np.array([s, corner, g]))
                break
    return out


def round_arc_bulges(problem: SwarmProblem, a: int) -> list[np.ndarray]:
    """The bulges (3,), m, of agent ``a``'s arcs round the obstacle its straight line passes through:
    per side (its left, then its right), the smallest multiple of :data:`AROUND_STEP_REACH` reach, at most
    :data:`AROUND_STEPS` steps, whose curve (:class:`~proxplan.planner.timing.arcs.ArcMove`'s quadratic,
    sampled every :data:`BLOCKED_SAMPLE_M` of its chord) is statically free ([] where its line is free,
    has no horizontal part, or :data:`ROUND_ARCS` is off). A function of the problem: kept in
    ``problem.static_memo``."""
    if not ROUND_ARCS:
        return []
    return problem.static_memo.get(("round arcs", a), partial(_round_arc_bulges, problem, a))


def _round_arc_bulges(problem: SwarmProblem, a: int) -> list[np.ndarray]:
    s, g = problem.starts_m[a], problem.goals_m[a]
    side = left_of_line(problem, a)
    if side is None or problem.segment_free(s, g):
        return []
    n = max(2, int(np.ceil(float(np.linalg.norm(g - s)) / BLOCKED_SAMPLE_M)) + 1)
    sigma = np.linspace(0.0, 1.0, n)[:, None]
    line = s[None] + sigma * (g - s)[None]
    out = []
    for sign in (1.0, -1.0):
        for k in range(1, AROUND_STEPS + 1):
            bulge = sign * k * AROUND_STEP_REACH * problem.reach_xy_m * side
            if bool(problem.static_free(line + 4.0 * sigma * (1.0 - sigma) * bulge[None]).all()):
                out.append(bulge)
                break
    return out


def _chains(problem: SwarmProblem, a: int, right_only: bool = False) -> list[np.ndarray]:
    """The straight line and the corner chains of a yielding vehicle (see module); ``right_only``:
    only the corners on its right (seen from above, heading to its goal), no straight line. A line
    through an obstacle: its chains round it (:func:`around_obstacle`), both sides."""
    s, g = problem.starts_m[a], problem.goals_m[a]
    if not problem.segment_free(s, g):
        return around_obstacle(problem, a)
    left = left_of_line(problem, a)
    side = left if left is not None else np.array([1.0, 0.0, 0.0])  # no horizontal line: x aside
    mid = 0.5 * (s + g)
    out = [] if right_only else [np.array([s, g])]
    for f in ASIDE_REACH_FACTORS:
        for sign in (-1.0,) if right_only else (1.0, -1.0):
            corner = mid + sign * f * problem.reach_xy_m * side
            if problem.static_free(corner[None])[0]:
                out.append(np.array([s, corner, g]))
    return out


def blockers(occ: Occupancy, problem: SwarmProblem, a: int) -> set[int]:
    """The agents whose tracks in ``occ`` meet agent ``a``'s straight line (where it leaves the static free
    space: its chains round the obstacle, :func:`around_obstacle`, each flown through its corner from t = 0),
    or ``a`` resting for good at its start or at its goal: the vehicles that hem a yielding vehicle in."""
    out: set[int] = set()
    for track in problem.static_memo.get(("blocker tracks", a), partial(_blocker_tracks, problem, a)):
        out |= occ.conflicting_agents(track)
    return out


def _blocker_tracks(problem: SwarmProblem, a: int) -> tuple[GridTrack, ...]:
    """The tracks :func:`blockers` asks about (a function of the problem alone, kept in
    ``problem.static_memo``: the passing stage asks them for every group placed late; read-only)."""
    s, g = problem.starts_m[a], problem.goals_m[a]
    ta = int(problem.type_index[a])
    if problem.segment_free(s, g):
        out = [own_straight_track(problem, a)]
    else:  # its routes round the obstacle (pillar-16 by type: hemmed in by the goals beside them, round 24S)
        out = [
            GridTrack(
                a, ta, s.copy(), [(0, RunMove(chain, problem.limits[a], GRID_DT_S, deviation_m=CORNER_DEVIATION_M))]
            )
            for chain in around_obstacle(problem, a)
        ]
    return (*out, GridTrack(a, ta, s.copy(), []), GridTrack(a, ta, g.copy(), []))


def _right_prediction(problem: SwarmProblem, a: int) -> GridTrack | None:
    """Agent ``a`` flown from t = 0 through the nearest corner on its right that is statically free,
    as a prediction that vanishes on arrival (None: no such corner, or no line)."""
    chains = _chains(problem, a, right_only=True)
    if not chains or problem.pinned[a] or np.allclose(problem.starts_m[a], problem.goals_m[a]):
        return None
    move = RunMove(chains[0], problem.limits[a], GRID_DT_S, deviation_m=CORNER_DEVIATION_M)
    track = GridTrack(a, int(problem.type_index[a]), problem.starts_m[a].copy(), [(0, move)])
    return track.vanishing(track.arrival_step + 1)


def _arc_bulges(problem: SwarmProblem, a: int, right_only: bool, factors: tuple[float, ...]) -> list[np.ndarray]:
    """The bulges (3,), m, of agent ``a``'s arcs: ``factors`` times the widest keep-out's horizontal
    reach, to either side of its line (to its right only with ``right_only``)."""
    side = left_of_line(problem, a)
    if side is None:  # a vertical line: no side to bulge to (its corners lie along x)
        return []
    signs = (-1.0,) if right_only else (1.0, -1.0)
    return [sign * f * problem.reach_xy_m * side for f in factors for sign in signs] + (
        round_arc_bulges(problem, a) if factors else []
    )


def time_yielding(
    occ: Occupancy,
    problem: SwarmProblem,
    a: int,
    right: bool,
    arrive_by: int | None,
    arc_factors: tuple[float, ...] = ARC_REACH_FACTORS,
):
    """The earliest :func:`time_chain` of agent ``a`` over its chains (:func:`_chains`) and the earliest
    :func:`time_arc` over its arcs (:func:`_arc_bulges` of ``arc_factors``), arriving by step
    ``arrive_by`` (None: any), or None."""
    best = None
    for chain in _chains(problem, a, right) or _chains(problem, a):
        bound = arrive_by if best is None else best.arrival_step - 1
        got = time_chain(occ, a, chain, arrive_by=bound, through=True)
        if got is not None and (best is None or got.arrival_step < best.arrival_step):
            best = got
    for bulge in _arc_bulges(problem, a, right, arc_factors):
        bound = arrive_by if best is None else best.arrival_step - 1
        got = time_arc(occ, a, bulge, arrive_by=bound)
        if got is not None and (best is None or got.arrival_step < best.arrival_step):
            best = got
    return best


def _place(
    problem: SwarmProblem,
    horizon_steps: int,
    yielders: set[int],
    first: list[int],
    right_hand: bool,
    leaders: frozenset[int] = frozenset(),
    arrive_by: int | None = None,
    arc_factors: tuple[float, ...] = ARC_REACH_FACTORS,
) -> tuple[dict[int, GridTrack] | None, int, set[int]]:
    """Every vehicle not in ``yielders`` on its straight line, each yielding vehicle timed after them,
    those of ``first`` first (the last raised first), the others longest line first (see module): (the
    tracks by agent, or None; the agent that could not be timed, -1 if none; the vehicles hemming it in)."""
    fixed = {a: own_straight_track(problem, a) for a in range(problem.n_agents) if a not in yielders}
    occ = Occupancy(problem, list(fixed.values()), horizon_steps)
    length = _line_lengths_m(problem)
    tracks = dict(fixed)
    predicted: set[int] = set()
    if right_hand:  # the yielding vehicles not timed yet: predicted on their smallest bulge to the right
        for a in yielders:
            if a in leaders:
                line = own_straight_track(problem, a)
                ghost: GridTrack | None = line.vanishing(line.arrival_step + 1)
            else:
                ghost = _right_prediction(problem, a)
            if ghost is not None:
                occ.put(ghost)
                predicted.add(a)
    raised = [a for a in reversed(first) if a in yielders]
    rest = sorted(
        (a for a in yielders if a not in raised), key=lambda a: (-tie_key(float(length[a]), LENGTH_RESOLUTION_M), a)
    )
    for a in raised + rest:
        occ.remove(a)
        predicted.discard(a)
        best = time_yielding(occ, problem, a, right_hand and a not in leaders, arrive_by, arc_factors)
        if best is None and predicted:  # the predictions hem it in: they are dropped, not the plan
            for b in predicted:
                occ.remove(b)
            predicted.clear()
            best = time_yielding(occ, problem, a, right_hand and a not in leaders, arrive_by, arc_factors)
        if best is None:
            return None, a, blockers(occ, problem, a)
        tracks[a] = best.track
        occ.put(best.track)
    return tracks, -1, set()


def yielding_stage(
    problem: SwarmProblem,
    horizon_steps: int,
    *,
    right_hand: bool = False,
    arrive_by: int | None = None,
    pairs: list[tuple[int, int]] | None = None,
    arc_factors: tuple[float, ...] = ARC_REACH_FACTORS,
) -> YieldResult:
    """The plan of the module (``horizon_steps``: grid steps of ``GRID_DT_S`` a timing may use;
    ``right_hand``: every vehicle in a conflicting pair yields, keeping to its right; ``arrive_by``:
    only a plan whose every vehicle arrives by this step is of interest, e.g. one shorter than a plan in
    hand; None: any; ``pairs``: the straight step's conflicts where already found; ``arc_factors``:
    the bulges of the arcs tried, :data:`ARC_REACH_FACTORS`; () for corners alone)."""
    if pairs is None:
        pairs = straight_step_conflicts(problem)
    if not pairs:
        return YieldResult(None, (), "no conflicting pair (the synchronised straight step is the plan)")
    if any(i == j for i, j in pairs):
        return YieldResult(None, (), "a straight line leaves the static free space: not this stage's case")
    yielders = (
        {a for pair in pairs for a in pair if not problem.pinned[a]}
        if right_hand
        else choose_yielders(problem, [(i, j) for i, j in pairs])
    )
    fixed = {a: own_straight_track(problem, a) for a in range(problem.n_agents) if a not in yielders}
    occ = Occupancy(problem, list(fixed.values()), horizon_steps)
    for a, tr in fixed.items():  # own-limit lines that meet on the grid (not in the synchronised test)
        hit = occ.conflicting_agents(tr) - yielders
        if hit:
            yielders |= {a} | {b for b in hit if not problem.pinned[b]}
    length = _line_lengths_m(problem)
    partners: dict[int, list[int]] = {}
    for i, j in pairs:
        partners.setdefault(i, []).append(j)
        partners.setdefault(j, []).append(i)
    # keeping right, a vehicle whose line is longer than each of its partners' keeps its line (the
    # partners' detours are the cheaper ones)
    leaders = frozenset(a for a, ps in partners.items() if right_hand and all(length[a] > length[b] + 1e-9 for b in ps))
    rounds = 0
    first: list[int] = []
    while True:
        tracks, stuck, hem = _place(
            problem, horizon_steps, yielders, first, right_hand, leaders, arrive_by, arc_factors
        )
        if tracks is not None:
            break
        grown = {b for b in hem if not problem.pinned[b]} - yielders
        rounds += 1
        raise_it = not grown and (not first or first[-1] != stuck)
        if not (grown or raise_it) or rounds > MAX_YIELD_ROUNDS:
            return YieldResult(
                None,
                tuple(sorted(yielders)),
                f"gave up after {rounds} round(s): vehicle {problem.names[stuck]} (yielding) has no timing along "
                f"its line or a corner or arc beside it arriving within "
                f"{(horizon_steps if arrive_by is None else arrive_by) * GRID_DT_S:.2f} s"
                + ("" if grown or raise_it else ", first already"),
            )
        if grown:
            yielders |= grown
        else:  # hemmed in by yielding vehicles timed before it: it goes first (a raised priority)
            first = [b for b in first if b != stuck] + [stuck]
    ordered = [tracks[a] for a in range(problem.n_agents)]
    note = (
        f"straight lines of {problem.n_agents - len(yielders)} vehicles, {len(yielders)} yielding "
        f"({len(pairs)} conflicting pairs of the synchronised step, {rounds + 1} round(s))"
    )
    return YieldResult(Stage(ordered, "prioritised", note, own_routes(problem, ordered)), tuple(sorted(yielders)), note)
