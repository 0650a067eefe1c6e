"""A smooth detour timed along its path: :class:`ArcMove` (issue 37 items 1 and 5).

The path is the parabola p(sigma) = p0 + sigma D + 4 sigma (1 - sigma) w for sigma in [0, 1] (world
frame, m): it leaves p0, bulges by ``w`` (the bulge at sigma = 1/2, m; any direction) and ends at p1 =
p0 + D. Its curvature is finite everywhere, so unlike a chain of corners (:class:`~proxplan.planner.timing.profile.RunMove`,
whose turns are rounded at a corner speed and whose straight stretches each speed up and slow down)
the vehicle never slows down along it except to start and stop.

It is timed along its parameter: sigma(t) = s(t) / |D| with s(t) the time-optimal jerk-limited rest-to-rest
profile over |D| (:func:`~proxplan.planner.timing.profile.rest_to_rest`, one degree of freedom). By the
chain rule, with p' = D + 4 (1 - 2 sigma) w and p'' = -8 w,

    v = p' sigma',  a = p'' sigma'^2 + p' sigma'',  j = 3 p'' sigma' sigma'' + p' sigma''',

so the 3-D speed, acceleration and jerk exceed the profile's where the path bends. The profile is
therefore first built at the vehicle's limits L, the norms of v, a and j sampled (:data:`CHECK_SAMPLES`
instants, jerk from the exact formula with sigma''' by finite differences of sigma''), and then built
again at the limits L scaled as a stretch of time by c >= 1 (speed / c, acceleration / c^2, jerk / c^3:
the time-optimal profile under those limits is the first one slowed down by c), with c the least that
brings every sampled norm within :data:`LIMIT_FRACTION` of L. The grid rounding of ``rest_to_rest`` only
slows it further. A bulge of zero is the straight line at the vehicle's limits (c = 1).

``ArcMove`` offers ``steps``, ``duration``, ``end_m``, ``positions()`` and ``at_time`` like
:class:`~proxplan.planner.timing.profile.LineMove`, so it is a move of a swarm track and a segment of a
:class:`~proxplan.planner.timing.paths.TimedPath`; the verifier checks the flown trajectory as every other.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from proxplan.physics import KinematicLimits
from proxplan.planner.timing.profile import Profile, rest_to_rest

# the sampled 3-D norms are kept within this fraction of the vehicle's limits: the samples may miss
# the exact peak (at 400 samples of a ~1-2 s move, 3-5 ms apart, the peak of a smooth norm is missed by
# far less than 1 %); the verifier allows 2 % on speed and acceleration and 10 % on jerk
# (verify.tolerances), so this margin keeps the plan off that edge too
LIMIT_FRACTION = 0.97
CHECK_SAMPLES = 400  # instants at which the norms of the first profile are sampled (see module)

__all__ = ["CHECK_SAMPLES", "LIMIT_FRACTION", "ArcMove", "arc_profile"]


def _norm_peaks(profile: Profile, chord_m: float, bulge_m: np.ndarray, delta_m: np.ndarray):
    """The largest norms (speed m/s, acceleration m/s^2, jerk m/s^3) of the arc flown along ``profile``."""
    t = np.linspace(0.0, profile.duration_s, CHECK_SAMPLES + 1)
    sav = np.array([profile.at(float(x)) for x in t])  # (M, 3): s m, s' m/s, s'' m/s^2
    sig = sav[:, 0] / chord_m
    d1, d2 = sav[:, 1] / chord_m, sav[:, 2] / chord_m
    d3 = np.gradient(d2, t)  # sigma''' by finite differences (the profile's jerk is piecewise constant)
    dp = delta_m[None] + (4.0 * (1.0 - 2.0 * sig))[:, None] * bulge_m[None]
    ddp = -8.0 * bulge_m
    v = dp * d1[:, None]
    a = ddp[None] * (d1**2)[:, None] + dp * d2[:, None]
    j = 3.0 * ddp[None] * (d1 * d2)[:, None] + dp * d3[:, None]
    return (float(np.linalg.norm(x, axis=1).max()) for x in (v, a, j))


@lru_cache(maxsize=4096)
def _cached_profile(chord_m: float, bulge_m: float, along_m: float, limits: KinematicLimits, dt_s: float) -> Profile:
    """:func:`arc_profile` of a chord of ``chord_m`` and a bulge of norm ``bulge_m`` whose component
    along the chord is ``along_m`` (m): the norms of v, a and j depend on nothing else (a rotation
    leaves them unchanged), so arcs of the same shape share one profile."""
    first = rest_to_rest(chord_m, limits, dt_s)
    if bulge_m <= 0.0:
        return first
    delta = np.array([chord_m, 0.0, 0.0])
    bulge = np.array([along_m, math.sqrt(max(bulge_m * bulge_m - along_m * along_m, 0.0)), 0.0])
    v, a, j = _norm_peaks(first, chord_m, bulge, delta)
    f = LIMIT_FRACTION
    c = max(
        1.0,
        v / (f * limits.max_speed_mps),
        math.sqrt(a / (f * limits.max_accel_mps2)),
        (j / (f * limits.max_jerk_mps3)) ** (1.0 / 3.0),
    )
    slowed = KinematicLimits(limits.max_speed_mps / c, limits.max_accel_mps2 / c**2, limits.max_jerk_mps3 / c**3)
    return rest_to_rest(chord_m, slowed, dt_s)


def arc_profile(p0_m: np.ndarray, p1_m: np.ndarray, bulge_m: np.ndarray, limits: KinematicLimits, dt_s: float):
    """The profile along the chord (see module) with which the arc p0 -> p1 (m) bulging by ``bulge_m``
    (m) stays within ``limits``, on the ``dt_s`` grid (s)."""
    delta = np.asarray(p1_m, dtype=float) - np.asarray(p0_m, dtype=float)
    bulge = np.asarray(bulge_m, dtype=float)
    chord = float(np.linalg.norm(delta))
    along = float(np.dot(bulge, delta)) / chord if chord > 0.0 else 0.0
    return _cached_profile(round(chord, 9), round(float(np.linalg.norm(bulge)), 9), round(along, 9), limits, dt_s)


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
        self.profile = arc_profile(self.p0, self.p0 + self.delta, self.bulge, limits, dt_s)
        self.duration = self.profile.duration_s
        self.steps = self.profile.steps
        self.end_m = self.p0 + self.delta
        self.waypoints_m = np.array([self.p0, self.p0 + 0.5 * self.delta + self.bulge, self.end_m])

    def __reduce__(self):  # its profile holds a Ruckig trajectory, which does not pickle: rebuilt
        return ArcMove, (self.p0, self.end_m, self.bulge, *self._args)

    def _point(self, sigma: np.ndarray | float):
        s = np.asarray(sigma, dtype=float)
        return self.p0 + s[..., None] * self.delta + (4.0 * s * (1.0 - s))[..., None] * self.bulge

    def at_time(self, t_s: float) -> tuple[list[float], list[float], list[float]]:
        """Position m, velocity m/s, acceleration m/s^2 at ``t_s`` after the start (rest outside)."""
        s, v, a = self.profile.at(t_s)
        if t_s >= self.duration:
            return self.end_m.tolist(), [0.0] * 3, [0.0] * 3
        sig, d1, d2 = s / self.chord_m, v / self.chord_m, a / self.chord_m
        dp = self.delta + 4.0 * (1.0 - 2.0 * sig) * self.bulge
        return (
            self._point(sig).tolist(),
            (dp * d1).tolist(),
            (-8.0 * self.bulge * d1 * d1 + dp * d2).tolist(),
        )

    def positions(self) -> np.ndarray:
        """Positions at every grid time 0, dt, ..., duration (steps + 1, 3), m."""
        out = self._point(self.profile.arc_m / self.chord_m)
        out[-1] = self.end_m
        return out
