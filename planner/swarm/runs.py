"""The vocabulary of the swarm search: an :class:`Agent` (one vehicle), a :class:`Move` (a wait or a
run), a vehicle's :class:`Path` with its (window, atom) occupancy, and the window occupancy of
straight jerk-limited rest-to-rest runs (:class:`Profiles`, from the exact Ruckig profile of the
motion flown later, :func:`proxplan.planner.timing.ruckig_segment`; cached per limits and distance)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from proxplan.physics import KinematicLimits
from proxplan.planner.timing.segments import ruckig_segment

INF_WINDOW = 1 << 30


@dataclass(frozen=True)
class Agent:
    """One vehicle for the search: its physics type index, limits class, start / goal endpoints."""

    name: str
    type_index: int
    limits: KinematicLimits
    start: int  # endpoint index
    goal: int  # endpoint index


@dataclass
class Move:
    """A wait (``run is None``) or a run from node ``a`` to node ``b`` starting at ``k0``."""

    k0: int
    n: int  # windows
    a: int  # node (lattice flat vertex, or V + endpoint)
    b: int
    duration_s: float  # flight time of the run (0 for a wait), s


@dataclass
class Path:
    """One vehicle's plan: moves, arrival window, occupancy (window, atom) until arrival, goal atom."""

    moves: list[Move]
    arrival: int
    occ_w: np.ndarray  # (K,) windows
    occ_a: np.ndarray  # (K,) atoms
    goal_atom: int
    expansions: int = 0
    blocked: dict = field(default_factory=dict)  # type index -> (windows, atoms) blocked for that type


class Profiles:
    """Window occupancy of rest-to-rest runs (cached per limits and distance)."""

    def __init__(self, window_s: float):
        self.window_s = window_s
        self._cache: dict = {}

    def run(self, limits: KinematicLimits, distance_m: float) -> tuple[float, np.ndarray]:
        """(duration s, (n, 2) swept [s_lo, s_hi] per window, m) of a straight rest-to-rest run."""
        key = (limits, round(distance_m, 6))
        hit = self._cache.get(key)
        if hit is None:
            traj = ruckig_segment(np.zeros(3), np.array([distance_m, 0.0, 0.0]), limits)
            dur = float(traj.duration)
            n = max(1, int(math.ceil(dur / self.window_s - 1e-9)))
            t = np.minimum(np.arange(n + 1) * self.window_s, dur)
            s = np.array([traj.at_time(float(x))[0][0] for x in t])
            s = np.maximum.accumulate(np.clip(s, 0.0, distance_m))
            hit = (dur, np.column_stack([s[:-1], s[1:]]))
            self._cache[key] = hit
        return hit
