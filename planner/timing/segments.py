"""Single Ruckig segments (community edition, state to state, never Ruckig's intermediate-waypoint
feature, which calls a cloud API): rest-to-rest phase-synchronised straight segments and
pass-through segments between moving states. Per-axis limits are the vehicle's norm limits scaled
so that the norms of velocity (m/s), acceleration (m/s^2) and jerk (m/s^3) stay within them.
"""

from __future__ import annotations

import numpy as np

from proxplan.physics import KinematicLimits


def ruckig_segment(p0_m, p1_m, limits: KinematicLimits, *, minimum_duration_s: float | None = None):
    """One rest-to-rest, phase-synchronised (straight-line) Ruckig segment from ``p0_m`` to
    ``p1_m`` (3,), m, taking at least ``minimum_duration_s``; a ``ruckig.Trajectory``."""
    from ruckig import InputParameter, Result, Synchronization, Trajectory

    p0 = np.asarray(p0_m, dtype=float)
    p1 = np.asarray(p1_m, dtype=float)
    d = p1 - p0
    dist = float(np.linalg.norm(d))
    u = np.abs(d) / dist
    eps = 1e-9
    inp = InputParameter(3)
    inp.current_position = p0.tolist()
    inp.target_position = p1.tolist()
    inp.current_velocity = [0.0, 0.0, 0.0]
    inp.target_velocity = [0.0, 0.0, 0.0]
    inp.max_velocity = (limits.max_speed_mps * u + eps).tolist()
    inp.max_acceleration = (limits.max_accel_mps2 * u + eps).tolist()
    inp.max_jerk = (limits.max_jerk_mps3 * u + eps).tolist()
    inp.synchronization = Synchronization.Phase
    if minimum_duration_s is not None:
        inp.minimum_duration = float(minimum_duration_s)
    traj = Trajectory(3)
    result = _OTG.calculate(inp, traj)
    if result not in (Result.Working, Result.Finished):
        raise RuntimeError(f"Ruckig failed on a segment ({result})")
    return traj


class _LazyOTG:
    def calculate(self, inp, traj):
        from ruckig import Ruckig

        global _OTG
        _OTG = Ruckig(3)
        return _OTG.calculate(inp, traj)


_OTG = _LazyOTG()


def through_segment(p0_m, p1_m, v0_mps, v1_mps, limits: KinematicLimits, *, straight: bool = False):
    """One Ruckig segment from ``p0_m`` moving at ``v0_mps`` to ``p1_m`` moving at ``v1_mps`` (3,),
    time-optimal; a ``ruckig.Trajectory``. ``straight`` (both velocities along the displacement):
    phase-synchronised, so the segment is a straight line; else time-synchronised.

    Per-axis limits ``L w_i`` with a unit weight vector w (the largest direction cosine of the
    displacement and of both velocities on each axis, normalised), so the norms of velocity,
    acceleration and jerk stay within the vehicle's limits L."""
    from ruckig import InputParameter, Result, Synchronization, Trajectory

    p0, p1 = np.asarray(p0_m, dtype=float), np.asarray(p1_m, dtype=float)
    v0, v1 = np.asarray(v0_mps, dtype=float), np.asarray(v1_mps, dtype=float)
    w = np.zeros(3)
    for vec in (p1 - p0, v0, v1):
        n = float(np.linalg.norm(vec))
        if n > 1e-12:
            w = np.maximum(w, np.abs(vec) / n)
    if not w.any():  # no displacement, at rest at both ends: a segment of no duration (any weights keep it so)
        w = np.ones(3)
    w = w / float(np.linalg.norm(w))
    eps = 1e-9
    inp = InputParameter(3)
    inp.current_position, inp.target_position = p0.tolist(), p1.tolist()
    inp.current_velocity, inp.target_velocity = v0.tolist(), v1.tolist()
    inp.max_velocity = (limits.max_speed_mps * w + eps).tolist()
    inp.max_acceleration = (limits.max_accel_mps2 * w + eps).tolist()
    inp.max_jerk = (limits.max_jerk_mps3 * w + eps).tolist()
    inp.synchronization = Synchronization.Phase if straight else Synchronization.Time
    traj = Trajectory(3)
    result = _OTG.calculate(inp, traj)
    if result not in (Result.Working, Result.Finished):
        raise RuntimeError(f"Ruckig failed on a pass-through segment ({result})")
    return traj
