"""Earliest arrival of one vehicle along a chain of waypoints, against the others' tracks.

The vehicle starts at rest at W_0 at t = 0 and must end at rest at W_m and hold it for good. From a
waypoint where it rests it may fly to a later one

* straight (a shortcut), rest-to-rest at its own limits
  (:func:`proxplan.planner.timing.profile.rest_to_rest`), when that line is statically free, or
* through the waypoints in between without stopping (a :class:`~proxplan.planner.timing.profile.RunMove`:
  one jerk-limited flight, corners rounded, speeds chosen locally), when its flown path is
  statically free,

and it may wait at any waypoint while holding it is clear. So it stops only where the search makes
it wait (or at a turn of 90 degrees or more). This is safe-interval path planning (Phillips and
Likhachev, 2011) on the chain: a state is (waypoint, safe interval of holding it), expanded in order
of arrival time plus the straight rest-to-rest time to the end (A*); a move from (k, I) departs at the earliest grid step in I that
:meth:`Occupancy.forbidden_departures` allows and whose arrival lands in a safe interval of the next
waypoint. Every move is checked on its flown grid samples against the tracks exactly, so the result
is conflict-free against them.
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass

import numpy as np

from proxplan.physics import KinematicLimits
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.problem import SwarmProblem
from proxplan.planner.swarm.tracks import GRID_DT_S, GridTrack, Move
from proxplan.planner.timing.profile import LineMove, RunMove, rest_to_rest

MAX_SHORTCUT = 6  # a straight move may skip at most this many waypoints (besides the direct move to the end)
MAX_RUN = 12  # a flight through waypoints spans at most this many (besides the one to the end)
STATIC_CHECKS_PER_STEP = 2  # a run's flown path is checked against the static free space this often per grid step
# a move to the end asks its departures in windows of this many steps at first (1.6 s), each later one
# as long as all before it: only the cost depends on it, never the answer
END_WINDOW_STEPS = 64


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """[start, end) index pairs of the True runs of ``mask``."""
    m = np.concatenate([[False], mask, [False]]).astype(np.int8)
    d = np.diff(m)
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist()))


def _live_arrivals(
    best: dict[tuple[int, int], int],
    j: int,
    runs: list[tuple[int, int]],
    starts: np.ndarray,
    a_lo: int,
    a_hi: int,
    T: int,
) -> tuple[int, int] | None:
    """The arrivals at waypoint ``j`` in [``a_lo``, ``a_hi``] (both safe to hold: in its safe
    intervals ``runs``, [first, end) steps, first steps ``starts``) that can still improve the search, as one range
    [first, last], or None: an interval that already has an arrival (``best``: (waypoint, interval)
    -> step) no later than the earliest one could be there (the later of ``a_lo`` and its first step)
    gains nothing from this move (the search keeps only strictly earlier arrivals, and only the
    first arrival in an interval), so the range runs from the first interval that can gain to the
    last. The departures of the move are asked only for those arrivals (exact, round 28B)."""
    i_lo = max(int(np.searchsorted(starts, a_lo, side="right")) - 1, 0)
    i_hi = int(np.searchsorted(starts, a_hi, side="right")) - 1
    live = [i for i in range(i_lo, i_hi + 1) if best.get((j, i), T + 1) > max(runs[i][0], a_lo)]
    if not live:
        return None
    return max(a_lo, runs[live[0]][0]), min(a_hi, runs[live[-1]][1] - 1)


class _Flown:
    """A move of a chain and its positions on the grid (computed when first asked: a run's are a
    Ruckig evaluation per step)."""

    __slots__ = ("move", "_samples")

    def __init__(self, move: Move):
        self.move = move
        self._samples: np.ndarray | None = None

    def samples(self) -> np.ndarray:
        if self._samples is None:
            self._samples = self.move.positions()
            self._samples.flags.writeable = False
        return self._samples


def _flown(
    problem: SwarmProblem, limits: KinematicLimits, W: np.ndarray, k: int, j: int, run: bool, dev: float
) -> _Flown | None:
    """The move W[k] -> W[j] at ``limits`` (through the waypoints between when ``run``, corners cut
    by at most ``dev``, m), None where it is not statically free. A move depends only on its
    waypoints, the limits, ``dev`` and the problem's static free space, so it is built once per
    problem (kept in ``problem.static_memo``) and every search along the same waypoints (a vehicle's
    chains re-timed pass after pass, planned again by the makespan repair) flies the same object."""
    pts = W[k : j + 1] if run else W[[k, j]]
    key = ("chain move", run, pts.shape, pts.tobytes(), limits, dev)

    def build() -> _Flown | None:
        mv: Move
        if run:
            rm = RunMove(pts, limits, GRID_DT_S, deviation_m=dev)
            free = bool(problem.static_free(rm.positions(STATIC_CHECKS_PER_STEP)).all())
            mv = rm
        else:
            free = problem.segment_free(pts[0], pts[1])
            mv = LineMove(pts[0], pts[1], rest_to_rest(float(np.linalg.norm(pts[1] - pts[0])), limits, GRID_DT_S))
        return _Flown(mv) if free else None

    return problem.static_memo.get(key, build)


@dataclass(frozen=True)
class ChainResult:
    track: GridTrack
    arrival_step: int


def time_chain(
    occ: Occupancy,
    agent: int,
    waypoints_m: np.ndarray,
    *,
    arrive_by: int | None = None,
    through: bool = True,
    deviation_m: float | None = None,
) -> ChainResult | None:
    """The earliest-arrival timing of ``agent`` along ``waypoints_m`` (m+1, 3), or None.

    ``arrive_by``: only results arriving no later than this step are of interest (prunes the
    search). ``through``: also fly through waypoints without stopping (else every move is
    rest-to-rest); ``deviation_m``: how far a rounding's chord may miss its corner, m (default
    :data:`proxplan.planner.timing.CORNER_DEVIATION_M`). Asked again against the same tracks
    (:meth:`Occupancy.content_key`) with the same arguments, the answer is given back, not searched
    again (:mod:`proxplan.planner.swarm.memo`)."""
    W = np.ascontiguousarray(waypoints_m, dtype=float)
    key = ("chain", occ.content_key(), agent, W.shape, W.tobytes(), arrive_by, through, deviation_m)
    return occ.problem.memo.get(
        key, lambda: _time_chain(occ, agent, W, arrive_by=arrive_by, through=through, deviation_m=deviation_m)
    )


def _time_chain(
    occ: Occupancy,
    agent: int,
    waypoints_m: np.ndarray,
    *,
    arrive_by: int | None,
    through: bool,
    deviation_m: float | None,
    end_window_steps: int = END_WINDOW_STEPS,
) -> ChainResult | None:
    """:func:`time_chain` searched (``end_window_steps``: the first window of a move to the end,
    :data:`END_WINDOW_STEPS`; the answer does not depend on it, tested)."""
    from proxplan.planner.timing import CORNER_DEVIATION_M

    problem = occ.problem
    W = np.asarray(waypoints_m, dtype=float)
    m = len(W) - 1
    T = occ.horizon
    limits = problem.limits[agent]
    dev = CORNER_DEVIATION_M if deviation_m is None else deviation_m
    # a waypoint's forbidden holds, safe intervals and their first steps, asked when the search first
    # needs them (a waypoint it never reaches is never asked; the answers are the same)
    hold_of: dict[int, tuple[np.ndarray, list[tuple[int, int]], np.ndarray]] = {}

    def held(k: int) -> tuple[np.ndarray, list[tuple[int, int]], np.ndarray]:
        got = hold_of.get(k)
        if got is None:
            hk = occ.forbidden_holds(agent, W[k])
            runs = _runs(~hk)
            got = hold_of[k] = (hk, runs, np.array([a for a, _ in runs], dtype=np.int64))
        return got

    if held(0)[0][0]:
        return None
    goal_intervals = held(m)[1]
    goal_ok = [e >= T for _, e in goal_intervals]
    if not any(goal_ok):
        return None
    # the moves, each with its grid samples, built once per problem (_flown: every search along the
    # same waypoints flies the same moves), and by identity the record of each move asked here
    moves: dict[tuple[int, int, bool], _Flown | None] = {}
    record: dict[int, _Flown] = {}

    def sampled(mv_: Move) -> np.ndarray:
        return record[id(mv_)].samples()

    # (from step, until step, departures): exact for departures in [from, until)
    forbidden: dict[tuple[int, int, bool], tuple[int, int, np.ndarray]] = {}

    def flown(k: int, j: int, run: bool) -> Move | None:
        """The move k -> j (through the waypoints between when ``run``), None where not statically free."""
        key = (k, j, run)
        if key not in moves:
            got = moves[key] = _flown(problem, limits, W, k, j, run, dev)
            if got is not None:
                record[id(got.move)] = got
        got = moves[key]
        return None if got is None else got.move

    def departures(k: int, j: int, run: bool, mv_: Move, lo: int, until: int) -> np.ndarray:
        """The move k -> j's forbidden departures, exact in [lo, until): a query serves every later
        one that starts no earlier and ends no later (a later safe interval at k starts after the
        end of this one: it asks again)."""
        key = (k, j, run)
        if key not in forbidden or forbidden[key][0] > lo or forbidden[key][1] < until:
            forbidden[key] = (lo, until, occ.forbidden_departures(agent, sampled(mv_), from_step=lo, until_step=until))
        return forbidden[key][2]

    # the end is held for good only from the start of its last safe interval (the one that lasts to
    # the horizon): an arrival there ends the search, an arrival in an earlier one of its intervals
    # leads nowhere (no move leaves the end), so a move to the end needs only its first departure
    # arriving from then on, found by asking the departures in growing windows (the same answer as
    # asking them all at once; only the cost depends on END_WINDOW_STEPS)
    goal_iv = len(goal_intervals) - 1
    goal_from = goal_intervals[goal_iv][0]
    # move key -> (first step, end step, forbidden departures, exact in [first, end))
    scanned: dict[tuple[int, bool], tuple[int, int, np.ndarray]] = {}

    def first_free(k: int, run: bool, mv_: Move, lo: int, hi: int) -> int | None:
        """The first departure in [lo, hi] that the others allow along the move k -> m (None: none)."""
        if hi < lo:
            return None
        got = scanned.get((k, run))
        if got is None or got[0] > lo:
            got = (lo, lo, np.zeros(T, dtype=bool))
        c0, c1, bad = got
        if c1 < lo:  # what was asked ends before lo: ask from lo (the steps between are of no use)
            c0, c1 = lo, lo
        d = lo
        while d <= hi:
            if d >= c1:  # ask the next window, as long as all asked before it (at least end_window_steps)
                c2 = min(hi + 1, c1 + max(end_window_steps, c1 - c0))
                bad[c1:c2] = occ.forbidden_departures(agent, sampled(mv_), from_step=c1, until_step=c2)[c1:c2]
                c1 = c2
                scanned[(k, run)] = (c0, c1, bad)
            free = np.flatnonzero(~bad[d : min(c1, hi + 1)])
            if free.size:
                return d + int(free[0])
            d = c1
        return None

    # A*: the rest-to-rest time of the straight line to the end bounds what is left (no flight
    # from rest to rest is faster, and the bound is consistent: straight rest-to-rest times are
    # subadditive)
    h = [rest_to_rest(float(np.linalg.norm(W[m] - W[k])), limits, GRID_DT_S).steps for k in range(m + 1)]
    best: dict[tuple[int, int], int] = {(0, 0): 0}
    parent: dict[tuple[int, int], tuple[int, int, int, Move]] = {}
    heap = [(h[0], 0, 0, 0)]
    limit = T if arrive_by is None else min(T, arrive_by + 1)
    done_by = limit  # the earliest arrival at the end found so far, +1 (nothing later is of interest)
    while heap:
        _, t, k, iv = heapq.heappop(heap)
        if best.get((k, iv), T + 1) < t or t + h[k] >= done_by:
            continue
        if k == m and goal_ok[iv]:
            out: list[tuple[int, Move]] = []
            node = (k, iv)
            while node in parent:
                pk, piv, dep, mv = parent[node]
                out.append((dep, mv))
                node = (pk, piv)
            track = GridTrack(agent, int(problem.type_index[agent]), W[0].copy(), out[::-1], route_m=W.copy())
            return ChainResult(track, t)
        _, e_iv = held(k)[1][iv]
        candidates = [(j, False) for j in range(k + 1, min(m, k + 1 + MAX_SHORTCUT) + 1)]
        if (m, False) not in candidates:
            candidates.append((m, False))
        if through:
            candidates += [(j, True) for j in range(k + 2, min(m, k + 1 + MAX_RUN) + 1)]
            if m >= k + 2 and (m, True) not in candidates:
                candidates.append((m, True))
        for j, run in candidates:
            if t + max(h[k], h[j]) >= done_by:  # cannot arrive at the end earlier through j
                continue
            if j == m and k < m:  # to the end: only its first departure into the goal's hold matters
                mv_end = flown(k, j, run)
                if mv_end is None:
                    continue
                n = mv_end.steps
                lo_d, hi_d = max(t, goal_from - n), min(e_iv - 1, done_by - 1 - n)
                d0 = first_free(k, run, mv_end, lo_d, hi_d)
                if d0 is not None and d0 + n < best.get((m, goal_iv), T + 1):
                    a0 = d0 + n
                    best[(m, goal_iv)] = a0
                    parent[(m, goal_iv)] = (k, iv, d0, mv_end)
                    heapq.heappush(heap, (a0, a0, m, goal_iv))
                    done_by = min(done_by, a0 + 1)
                continue
            mv_j = flown(k, j, run)
            if mv_j is None:
                continue
            n = mv_j.steps
            # departures after done_by - 1 - steps - h[j] cannot improve on the best arrival found (and
            # done_by only decreases), those from e on leave a hold that is no longer safe
            lo_d, hi_d = t, min(e_iv - 1, done_by - 1 - n - h[j])
            if hi_d < lo_d:
                continue
            # only departures arriving where holding j is safe lead anywhere: the others' tracks are
            # asked from the first such departure to the last (the same departures are kept)
            hold_j, _, starts = held(j)
            safe = np.flatnonzero(~hold_j[lo_d + n : hi_d + n + 1])
            if safe.size == 0:
                continue
            lo_d, hi_d = lo_d + int(safe[0]), lo_d + int(safe[-1])
            live = _live_arrivals(best, j, held(j)[1], starts, lo_d + n, hi_d + n, T)
            if live is None:
                continue  # no arrival of this move can improve on one found: not asked
            lo_d, hi_d = live[0] - n, live[1] - n
            bad = departures(k, j, run, mv_j, lo_d, hi_d + 1)
            deps = np.flatnonzero(~bad[lo_d : hi_d + 1]) + lo_d
            if deps.size == 0:
                continue
            arrs = deps + n
            ok = ~hold_j[arrs]
            deps, arrs = deps[ok], arrs[ok]
            if deps.size == 0:
                continue
            ivs = np.searchsorted(starts, arrs, side="right") - 1
            seen: set[int] = set()
            for d0, a0, i0 in zip(deps.tolist(), arrs.tolist(), ivs.tolist()):
                if i0 in seen:
                    continue
                seen.add(i0)
                if a0 < best.get((j, i0), T + 1):
                    best[(j, i0)] = a0
                    parent[(j, i0)] = (k, iv, d0, mv_j)
                    heapq.heappush(heap, (a0 + h[j], a0, j, i0))
                    if j == m and goal_ok[i0]:
                        done_by = min(done_by, a0 + 1)
    return None
