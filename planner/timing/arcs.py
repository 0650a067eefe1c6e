"""A smooth detour timed along its path: :class:`ArcMove` (issue 37 items 1 and 5).

The path is the parabola p(sigma) = p0 + sigma D + 4 sigma (1 - sigma) w for sigma in [0, 1] (world
frame, m): it leaves p0, bulges by ``w`` (the bulge at sigma = 1/2, m; any direction) and ends at p1 =
p0 + D. Its curvature is finite everywhere, so unlike a chain of corners (:class:`~proxplan.planner.timing.profile.RunMove`,
whose turns are rounded at a corner speed and whose straight stretches each speed up and slow down)
the vehicle never slows down along it except to start and stop.

It is timed along its parameter by :func:`~proxplan.planner.timing.path_law.quadratic_law`: a jerk-limited
law sigma(t) whose speed along the path is chosen pointwise (near time-optimal under the norms of the
vehicle's speed, acceleration and jerk, exact against them on the grid; round 27S). Round 21S's timing
(the chord's rest-to-rest profile slowed down uniformly until the arc's norms fit) is replaced: on the
0.6 m swaps of grid-64 at half a reach aside it took 64 grid steps, the law takes 55. A bulge of zero
is the straight line at the vehicle's limits (:func:`~proxplan.planner.timing.profile.rest_to_rest`).

``ArcMove`` offers ``steps``, ``duration``, ``end_m``, ``positions()`` and ``at_time`` like
:class:`~proxplan.planner.timing.profile.LineMove`, so it is a move of a swarm track and a segment of a
:class:`~proxplan.planner.timing.paths.TimedPath`; the verifier checks the flown trajectory as every other.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from proxplan.physics import KinematicLimits
from proxplan.planner.timing.path_law import PathLaw, quadratic_law
from proxplan.planner.timing.profile import Profile, rest_to_rest

__all__ = ["ArcMove"]


@dataclass(frozen=True)
class _ChordLaw:
    """sigma(t) = s(t) / |D| along a rest-to-rest ``profile`` over the chord (a bulge of zero)."""

    profile: Profile

    @property
    def steps(self) -> int:
        return self.profile.steps

    @property
    def duration_s(self) -> float:
        return self.profile.duration_s

    def at(self, t_s: float) -> tuple[float, float, float]:
        s, v, a = self.profile.at(t_s)
        d = self.profile.distance_m
        return s / d, v / d, a / d

    def sigma_grid(self) -> np.ndarray:
        return self.profile.arc_m / self.profile.distance_m


class ArcMove:
    """The arc p0 -> p1 (m) bulging by ``bulge_m`` (m) at its middle, flown from rest to rest within
    ``limits`` on the ``dt_s`` grid (see module)."""

    def __init__(self, p0_m: np.ndarray, p1_m: np.ndarray, bulge_m: np.ndarray, limits: KinematicLimits, dt_s: float):
        self.p0 = np.asarray(p0_m, dtype=float)
        self.delta = np.asarray(p1_m, dtype=float) - self.p0
        self.bulge = np.asarray(bulge_m, dtype=float)
        self.chord_m = float(np.linalg.norm(self.delta))
        if self.chord_m <= 1e-9:
            raise ValueError("an arc needs distinct ends")
        self._args = (limits, dt_s)
        self.end_m = self.p0 + self.delta
        self.law: PathLaw | _ChordLaw
        if float(np.linalg.norm(self.bulge)) <= 0.0:
            self.law = _ChordLaw(rest_to_rest(self.chord_m, limits, dt_s))
        else:
            self.law = quadratic_law(self.p0, self.end_m, self.bulge, limits, dt_s)
        self.duration = self.law.duration_s
        self.steps = self.law.steps
        self.waypoints_m = np.array([self.p0, self.p0 + 0.5 * self.delta + self.bulge, self.end_m])
        self._grid = self._point(self.law.sigma_grid())
        self._grid[-1] = self.end_m

    def __reduce__(self):  # rebuilt from its arguments (the law is cached by shape, deterministically)
        return ArcMove, (self.p0, self.end_m, self.bulge, *self._args)

    def _point(self, sigma: np.ndarray | float):
        s = np.asarray(sigma, dtype=float)
        return self.p0 + s[..., None] * self.delta + (4.0 * s * (1.0 - s))[..., None] * self.bulge

    def at_time(self, t_s: float) -> tuple[list[float], list[float], list[float]]:
        """Position m, velocity m/s, acceleration m/s^2 at ``t_s`` after the start (rest outside)."""
        if t_s >= self.duration:
            return self.end_m.tolist(), [0.0] * 3, [0.0] * 3
        sig, d1, d2 = self.law.at(t_s)
        dp = self.delta + 4.0 * (1.0 - 2.0 * sig) * self.bulge
        return (
            self._point(sig).tolist(),
            (dp * d1).tolist(),
            (-8.0 * self.bulge * d1 * d1 + dp * d2).tolist(),
        )

    def positions(self) -> np.ndarray:
        """Positions at every grid time 0, dt, ..., duration (steps + 1, 3), m."""
        return self._grid.copy()
