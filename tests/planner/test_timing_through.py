"""Pass-through timing (proxplan.planner.timing.time_parameterize_through): chained state-to-state Ruckig
segments with non-zero velocities at interior waypoints, within the vehicle's norm limits."""

from __future__ import annotations

import numpy as np

from proxplan.physics import KinematicLimits
from proxplan.planner.timing import time_parameterize, time_parameterize_through

LIM = KinematicLimits(1.5, 3.0, 15.0)


def _norms(tp, dt=0.002):
    t = np.arange(0.0, tp.duration_s, dt)
    p, v, a = tp.sample(t)
    jerk = np.linalg.norm(np.diff(a, axis=0), axis=1) / dt
    return t, p, np.linalg.norm(v, axis=1), np.linalg.norm(a, axis=1), jerk


def test_corner_is_passed_moving_faster_than_rest_to_rest_and_within_limits():
    pts = np.array([[0.0, 0.0, 1.0], [1.5, 0.2, 1.2], [3.0, 1.5, 1.5], [3.5, 3.0, 1.5]])
    rest = time_parameterize(pts, None, LIM)
    through = time_parameterize_through(pts, np.zeros(len(pts)), LIM)
    assert through.duration_s < 0.95 * rest.duration_s
    t, p, speed, acc, jerk = _norms(through)
    assert speed.max() <= LIM.max_speed_mps * (1 + 1e-6)
    assert acc.max() <= LIM.max_accel_mps2 * (1 + 1e-6)
    assert jerk.max() <= LIM.max_jerk_mps3 * 1.05  # finite differences
    k = int(np.argmin(np.abs(t - through.knot_t_s[1])))
    assert speed[k] > 0.2  # moving at the first interior waypoint
    np.testing.assert_allclose(through.sample(np.array([through.duration_s + 1.0]))[0][0], pts[-1], atol=1e-9)


def test_waits_end_at_their_scheduled_time_and_reversals_stop():
    pts = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [0.0, 0.0, 1.0]])
    tp = time_parameterize_through(pts, np.array([0.0, 2.0, 0.0, 0.0]), LIM)
    assert tp.segments[0] is None and abs(tp.knot_t_s[1] - 2.0) < 1e-12  # wait at the start until t = 2 s
    _, v, _ = tp.sample(np.array([tp.knot_t_s[2]]))
    assert np.linalg.norm(v[0]) < 1e-6  # a 180 degree turn is flown through rest
