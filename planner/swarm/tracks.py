"""Timed trajectories of the swarm layer on its time grid (:class:`GridTrack`).

A :class:`GridTrack` is what one vehicle flies: it rests at its start, then flies a sequence of
non-overlapping moves - straight rest-to-rest :class:`~proxplan.planner.timing.profile.LineMove` s
and flights through waypoints :class:`~proxplan.planner.timing.profile.RunMove` s - each starting
and ending on a grid step of ``GRID_DT_S``, resting between them, and parks at its last position for
good. ``positions_m`` samples it on the grid and ``moving`` tells the samples at which the vehicle
moves (speed of at least the verifier's ``REST_SPEED_MPS``, on either side of the sample), so pairs
at rest are compared without the tracking tube, as the verifier does.

A *predicted* track (``vanishes``) is an assumption about a vehicle not planned yet: it flies the
first part of its straight route and is then no longer counted (it does not park).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from proxplan.planner.timing.paths import TimedPath
from proxplan.verify import REST_SPEED_MPS

GRID_DT_S = 0.025  # time grid of the swarm layer, s (plan.json's 0.05 s is a multiple)


class Move(Protocol):
    """A move on the grid: starts and ends at rest, lasts ``steps`` grid steps."""

    steps: int
    duration: float
    end_m: np.ndarray

    def positions(self) -> np.ndarray: ...

    def at_time(self, t_s: float) -> tuple[list[float], list[float], list[float]]: ...


@dataclass
class GridTrack:
    """One vehicle's trajectory (see module); ``moves`` holds (start step, move) in time order."""

    agent: int
    type: int
    start_m: np.ndarray
    moves: Sequence[tuple[int, Move]] = field(default_factory=list)
    vanishes: bool = False  # a prediction: gone after its last sample (it does not park)
    route_m: np.ndarray | None = None  # (m+1, 3) the waypoint chain it was timed along, m (None: none kept)
    positions_m: np.ndarray = field(init=False)  # (n + 1, 3), m: sample k at k GRID_DT_S
    moving: np.ndarray = field(init=False)  # (n + 1,) bool
    in_move: np.ndarray = field(init=False)  # (n + 1,) bool: the sample belongs to a move (its ends included)
    lo_m: np.ndarray = field(init=False)  # (3,) bounding box of the whole track, m
    hi_m: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        pts = [np.asarray(self.start_m, dtype=float)[None]]
        t = 0
        cur = pts[0][0]
        spans = []
        for k0, mv in self.moves:
            spans.append((k0, k0 + mv.steps))
            if k0 < t:
                raise ValueError(f"track of agent {self.agent}: a move starts at step {k0} before step {t}")
            if k0 > t:
                pts.append(np.repeat(cur[None], k0 - t, axis=0))
            seg = mv.positions()
            pts.append(seg[1:])
            t = k0 + mv.steps
            cur = seg[-1]
        self.positions_m = np.concatenate(pts, axis=0)
        n = self.positions_m.shape[0]
        speed = np.linalg.norm(np.diff(self.positions_m, axis=0), axis=1) / GRID_DT_S if n > 1 else np.zeros(0)
        fast = speed >= REST_SPEED_MPS * 0.5
        self.moving = np.r_[fast, False] | np.r_[False, fast]
        self.in_move = np.zeros(n, dtype=bool)
        for a, b in spans:
            self.in_move[a : b + 1] = True
        self.lo_m = self.positions_m.min(axis=0)
        self.hi_m = self.positions_m.max(axis=0)

    def vanishing(self, n: int) -> GridTrack:
        """The first ``n`` samples of this track as a prediction that vanishes after them."""
        out = GridTrack(self.agent, self.type, self.start_m, list(self.moves), vanishes=True)
        idx = np.minimum(np.arange(n), self.arrival_step)  # parked beyond the end
        out.positions_m, out.moving = self.positions_m[idx].copy(), self.moving[idx].copy()
        out.in_move = self.in_move[idx] & (np.arange(n) <= self.arrival_step)
        out.lo_m, out.hi_m = out.positions_m.min(axis=0), out.positions_m.max(axis=0)
        return out

    def relabel(self, agent: int) -> GridTrack:
        """The same trajectory for agent index ``agent`` (components planned apart)."""
        return GridTrack(agent, self.type, self.start_m, list(self.moves), self.vanishes, self.route_m)

    @property
    def arrival_step(self) -> int:
        """Grid step at which the track comes to rest at its end for good."""
        return self.positions_m.shape[0] - 1

    @property
    def arrival_s(self) -> float:
        return self.arrival_step * GRID_DT_S

    @property
    def end_m(self) -> np.ndarray:
        return self.positions_m[-1]

    def position_at_steps(self, steps: np.ndarray) -> np.ndarray:
        """Positions (M, 3) at grid steps ``steps`` (M,) (parked after the end), m."""
        k = np.minimum(np.asarray(steps, dtype=np.int64), self.arrival_step)
        return self.positions_m[k]

    def timed_path(self) -> TimedPath:
        """The same trajectory as a :class:`TimedPath` (holds as ``None`` segments)."""
        knots = [0.0]
        pts = [np.asarray(self.start_m, dtype=float)]
        segs: list = []
        t = 0
        for k0, mv in self.moves:
            if k0 > t:
                segs.append(None)
                knots.append(k0 * GRID_DT_S)
                pts.append(pts[-1])
            segs.append(mv)
            t = k0 + mv.steps
            knots.append(t * GRID_DT_S)
            pts.append(np.asarray(mv.end_m, dtype=float))
        return TimedPath(np.array(knots), np.array(pts), segs)
