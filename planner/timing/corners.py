"""Flying through waypoints without stopping: the speed at each waypoint, chosen locally, and the
jerk-limited Ruckig segments of the run (state to state, never Ruckig's intermediate-waypoint
feature, which calls a cloud API). World frame; m, m/s.

A run starts at rest at its first waypoint and ends at rest at its last. An interior waypoint with
a turn of less than 90 degrees is passed moving: its corner is *rounded* between the points
r = ``deviation_m`` / sin(turn / 2) before and after it on its two legs (at most half of either
leg), so the path cuts the corner by at most ``deviation_m`` (the chord between them misses the
corner by r sin(turn / 2)); the rounding is one time-synchronised segment from velocity s along the
first leg to s along the second, and the straight stretches between roundings are
phase-synchronised segments (straight lines). Turns of 90 degrees or more are flown through rest.

The speed s at a corner is the least of (:func:`corner_speeds`): v_max; turning the velocity over
the rounding (length about 2 r) within the vehicle's acceleration and jerk; the per-axis velocity
limits with which :func:`~proxplan.planner.timing.segments.through_segment` flies the rounding (so
Ruckig accepts the states); and reachability, forward and backward passes so that each straight
stretch is long enough for its jerk-limited speed change (:func:`change_distance_m`). Ruckig's
per-axis limits make the rounding anisotropic, so the run
is then built and a rounding that takes longer than ``ROUNDING_SLACK`` x its chord at speed s has
its corner speed cut by ``SPEED_BACKOFF`` and the run rebuilt (at most ``MAX_BACKOFFS`` times, then
that corner is flown through rest). Speeds and limits are the vehicle's norm limits (through_segment
keeps the norms within them).
"""

from __future__ import annotations

import math

import numpy as np

from proxplan.physics import KinematicLimits
from proxplan.planner.ties import tie_key
from proxplan.planner.timing.segments import through_segment

# how far the chord of a rounding may miss its corner, m (the flown rounding lies between chord and
# corner; on 45-degree corners of 1 m legs it cut 4-6 cm, Ruckig, small-quad limits). It sets
# quality, not safety: the planners check every flown trajectory exactly. Chosen on those test
# corners: 7.5 cm gained 7 % over stopping, 15 cm 17 %, 30 cm no more than 15 cm
CORNER_DEVIATION_M = 0.15
ROUNDING_SLACK = 1.5  # a rounding may take this much longer than its chord at the corner speed ...
SPEED_BACKOFF = 0.7  # ... else the corner speed is cut by this factor and the run rebuilt ...
MAX_BACKOFFS = 6  # ... at most this many times (then the corner is flown through rest)
# turns of 90 degrees or more (cosine at or below this) are flown through rest: a rounded right
# angle at the corner speed the jerk allows takes as long as stopping there (measured with Ruckig)
MAX_TURN_COS = 0.0
# the turn's cosine is compared with MAX_TURN_COS after rounding to this resolution (dimensionless), by
# :func:`proxplan.planner.ties.tie_key` as every machine-independent choice is (issue 37, round 37U): a right angle
# is common by construction (a lane route's offset legs are perpendicular to its middle leg), and its cosine,
# 0 exactly, comes out as +-1e-17 by the last bits of its legs, which differ from machine to machine (numpy's
# SIMD kernels). Far above float64's error on a cosine of unit vectors (~1e-16), far below any turn a run
# resolves (1e-9 rad off a right angle)
TURN_COS_RESOLUTION = 1e-9


def passes_moving(cos_turn: float) -> bool:
    """A turn of cosine ``cos_turn`` is passed moving (rounded): under 90 degrees, its cosine above
    ``MAX_TURN_COS`` once both are rounded to ``TURN_COS_RESOLUTION`` (a right angle within float64's
    error is flown through rest on every machine)."""
    return tie_key(cos_turn, TURN_COS_RESOLUTION) > tie_key(MAX_TURN_COS, TURN_COS_RESOLUTION)


def _geometry(pts: np.ndarray, deviation_m: float):
    """Leg lengths (K-1,), leg directions (K-1, 3), rounding radius r (K,) and sin(turn / 2) (K,)
    (r = 0 where the waypoint is passed at rest or straight on)."""
    d = np.diff(pts, axis=0)
    length = np.linalg.norm(d, axis=1)
    u = d / np.maximum(length, 1e-12)[:, None]
    K = len(pts)
    radius, half_sin = np.zeros(K), np.ones(K)
    for m in range(1, K - 1):
        if length[m - 1] < 1e-9 or length[m] < 1e-9:
            continue
        cos_turn = float(np.clip(np.dot(u[m - 1], u[m]), -1.0, 1.0))
        half_sin[m] = math.sqrt((1.0 - cos_turn) / 2.0)
        if passes_moving(cos_turn) and half_sin[m] > 1e-9:
            radius[m] = min(deviation_m / half_sin[m], 0.5 * length[m - 1], 0.5 * length[m])
    return length, u, radius, half_sin


def change_distance_m(v0_mps: float, v1_mps: float, limits: KinematicLimits) -> float:
    """Distance, m, that a jerk-limited speed change from ``v0`` to ``v1`` along a line takes (an
    S-curve from zero to zero acceleration): time T = dv / a + a / j when the acceleration limit is
    reached (dv >= a^2 / j), else 2 sqrt(dv / j); distance (v0 + v1) / 2 x T (the S-curve is
    symmetric)."""
    dv = abs(v1_mps - v0_mps)
    a, j = limits.max_accel_mps2, limits.max_jerk_mps3
    t = dv / a + a / j if dv >= a * a / j else 2.0 * math.sqrt(dv / j)
    return 0.5 * (v0_mps + v1_mps) * t


def _fastest_after(v0: float, room_m: float, cap: float, limits: KinematicLimits) -> float:
    """The largest speed <= ``cap`` reachable from ``v0`` (or down to from it) within ``room_m``."""
    if change_distance_m(v0, cap, limits) <= room_m:
        return cap
    lo, hi = 0.0 if cap < v0 else v0, cap
    if cap >= v0:
        for _ in range(40):  # bisection on the speed gained within the room
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if change_distance_m(v0, mid, limits) <= room_m else (lo, mid)
        return lo
    return cap  # slowing down to ``cap`` is handled by the backward pass from the lower side


def _reachable(speed: np.ndarray, stretch: np.ndarray, limits: KinematicLimits) -> None:
    """Forward and backward passes over the straight stretches (in place; ends at rest): no
    stretch has to overshoot to meet its end speeds (:func:`change_distance_m`)."""
    K = speed.size
    speed[0] = speed[-1] = 0.0
    for m in range(1, K):
        speed[m] = _fastest_after(float(speed[m - 1]), max(float(stretch[m - 1]), 0.0), float(speed[m]), limits)
    for m in range(K - 2, -1, -1):
        speed[m] = _fastest_after(float(speed[m + 1]), max(float(stretch[m]), 0.0), float(speed[m]), limits)


def corner_speeds(pts: np.ndarray, limits: KinematicLimits, *, deviation_m: float = CORNER_DEVIATION_M) -> np.ndarray:
    """First choice of the speed (K,), m/s, at each waypoint of a run through ``pts`` (K, 3), m (see
    module): zero at the ends and at turns of 90 degrees or more."""
    pts = np.asarray(pts, dtype=float).reshape(-1, 3)
    K = len(pts)
    speed = np.zeros(K)
    if K < 3:
        return speed
    length, u, radius, half_sin = _geometry(pts, deviation_m)
    vmax, amax = limits.max_speed_mps, limits.max_accel_mps2
    for m in range(1, K - 1):
        if length[m - 1] < 1e-9 or length[m] < 1e-9 or not passes_moving(float(np.dot(u[m - 1], u[m]))):
            continue
        if radius[m] <= 0.0:  # straight on
            speed[m] = vmax
            continue
        bisector = (u[m - 1] + u[m]) / float(np.linalg.norm(u[m - 1] + u[m]))
        w = np.maximum(np.maximum(np.abs(u[m - 1]), np.abs(u[m])), np.abs(bisector))  # as through_segment
        w = w / float(np.linalg.norm(w))
        room = min(
            float(np.min(np.where(c > 1e-12, vmax * w / np.maximum(c, 1e-12), np.inf)))
            for c in (np.abs(u[m - 1]), np.abs(u[m]))
        )
        # turning the velocity by the turn angle over the rounding (chord about 2 r, time 2 r / s):
        # the lateral speed change s sin(turn) needs s^2 <= 2 a r / sin(turn) at acceleration a and
        # s^3 <= j r^2 / sin(turn) at jerk j (a triangle of acceleration over the rounding)
        sin_turn = 2.0 * half_sin[m] * math.sqrt(max(0.0, 1.0 - half_sin[m] ** 2))
        lateral = max(sin_turn, half_sin[m])
        jmax = limits.max_jerk_mps3
        speed[m] = min(
            vmax,
            math.sqrt(2.0 * amax * radius[m] / lateral),
            (jmax * radius[m] ** 2 / lateral) ** (1.0 / 3.0),
            room * (1.0 - 1e-9),
        )
    _reachable(speed, length - radius[:-1] - radius[1:], limits)
    return speed


def _states(pts, speed, length, u, radius):
    """(points (P, 3), velocities (P, 3), straight (P-1,), corner (P-1,): the waypoint a rounding
    belongs to, -1 for straight stretches)."""
    out_p, out_v = [pts[0]], [np.zeros(3)]
    straight: list[bool] = []
    corner: list[int] = []
    K = len(pts)
    for m in range(1, K):
        moving = m < K - 1 and speed[m] > 0.0
        if not moving or radius[m] <= 0.0:  # at rest, or straight on through the waypoint itself
            out_p.append(pts[m])
            out_v.append(speed[m] * u[m - 1] if moving else np.zeros(3))
            straight.append(True)
            corner.append(-1)
            continue
        a_pt, b_pt = pts[m] - radius[m] * u[m - 1], pts[m] + radius[m] * u[m]
        if float(np.linalg.norm(a_pt - out_p[-1])) > 1e-9:
            out_p.append(a_pt)
            out_v.append(speed[m] * u[m - 1])
            straight.append(True)
            corner.append(-1)
        else:  # the previous rounding ends where this one starts (both take half the leg)
            out_v[-1] = min(float(np.linalg.norm(out_v[-1])), float(speed[m])) * u[m - 1]
        out_p.append(b_pt)
        out_v.append(speed[m] * u[m])
        straight.append(False)
        corner.append(m)
    return np.array(out_p), np.array(out_v), straight, corner


def through_run(pts: np.ndarray, limits: KinematicLimits, *, deviation_m: float = CORNER_DEVIATION_M) -> list:
    """The Ruckig segments (``ruckig.Trajectory``, time-optimal) of a run from rest at ``pts[0]``
    through the interior waypoints to rest at ``pts[-1]`` (K >= 2, 3), m (see module). The
    roundings are not straight: callers check the flown trajectory."""
    pts = np.asarray(pts, dtype=float).reshape(-1, 3)
    speed = corner_speeds(pts, limits, deviation_m=deviation_m)
    length, u, radius, _ = _geometry(pts, deviation_m)
    for attempt in range(MAX_BACKOFFS + 2):
        P, V, straight, corner = _states(pts, speed, length, u, radius)
        pieces = [
            through_segment(P[k], P[k + 1], V[k], V[k + 1], limits, straight=straight[k]) for k in range(len(P) - 1)
        ]
        slow = set()
        for k, m in enumerate(corner):
            if m >= 0:
                chord = float(np.linalg.norm(P[k + 1] - P[k]))
                if float(pieces[k].duration) > ROUNDING_SLACK * chord / max(float(speed[m]), 1e-9):
                    slow.add(m)
        if not slow or attempt == MAX_BACKOFFS + 1:
            return pieces
        for m in slow:
            speed[m] = 0.0 if attempt == MAX_BACKOFFS else speed[m] * SPEED_BACKOFF
        _reachable(speed, length - radius[:-1] - radius[1:], limits)
    return pieces
