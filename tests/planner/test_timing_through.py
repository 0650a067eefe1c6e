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


def _polyline_distance(p, pts):
    best = np.full(len(p), np.inf)
    for a, b in zip(pts[:-1], pts[1:]):
        ab = b - a
        s = np.clip((p - a) @ ab / (ab @ ab), 0.0, 1.0)
        best = np.minimum(best, np.linalg.norm(p - a - s[:, None] * ab, axis=1))
    return best


def test_a_run_rounds_its_corners_within_the_deviation_and_the_limits():
    """A flight through waypoints (RunMove): corners of less than 90 degrees are passed moving, the
    path stays within the corner deviation of the polyline, norms stay within the limits, it starts
    and ends at rest on the grid, and on these corners it is faster than stopping at each."""
    from proxplan.planner.timing.profile import RunMove, rest_to_rest

    pts = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [1.7, 0.7, 1.0], [1.7, 2.0, 1.0]])
    dev = 0.15
    run = RunMove(pts, LIM, 0.025, deviation_m=dev)
    stops = sum(rest_to_rest(float(np.linalg.norm(b - a)), LIM, 0.025).duration_s for a, b in zip(pts[:-1], pts[1:]))
    assert run.duration < 0.9 * stops
    assert abs(run.duration / 0.025 - run.steps) < 1e-9
    q = run.positions(4)
    np.testing.assert_allclose(q[0], pts[0])
    np.testing.assert_allclose(q[-1], pts[-1])
    assert _polyline_distance(q, pts).max() <= dev
    t = np.arange(0.0, run.duration, 0.002)
    v = np.array([run.at_time(x)[1] for x in t])
    a = np.array([run.at_time(x)[2] for x in t])
    assert np.linalg.norm(v, axis=1).max() <= LIM.max_speed_mps * (1 + 1e-6)
    assert np.linalg.norm(a, axis=1).max() <= LIM.max_accel_mps2 * (1 + 1e-6)
    assert (np.linalg.norm(np.diff(a, axis=0), axis=1) / 0.002).max() <= LIM.max_jerk_mps3 * 1.05
    assert np.linalg.norm(run.at_time(run.duration)[1]) == 0.0
    corner = int(np.argmin(np.linalg.norm(np.array([run.at_time(x)[0] for x in t]) - pts[1], axis=1)))
    assert np.linalg.norm(v[corner]) > 0.3  # moving at the first corner


def test_a_right_angle_is_flown_through_rest():
    from proxplan.planner.timing import corner_speeds

    pts = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [1.0, 1.0, 1.0], [2.0, 1.0, 1.0]])
    speeds = corner_speeds(pts, LIM)
    assert speeds.tolist() == [0.0, 0.0, 0.0, 0.0]


def test_a_rest_to_rest_move_a_rounding_error_off_a_profile_boundary_is_planned():
    """At 2 m/s, 4 m/s^2, 16 m/s^3 the acceleration just reaches its limit over 2 a^3 / j^2 = 0.5 m;
    Ruckig raises on 0.4999999999999999 m (a lattice step computed by rounding, where the swarm
    layer's lock-step plan crashed on pillar-64): the move is planned, ends where asked, and keeps
    the limits."""
    from proxplan.planner.timing.profile import rest_to_rest

    lim = KinematicLimits(2.0, 4.0, 16.0)
    distance = 0.4999999999999999
    prof = rest_to_rest(distance, lim, 0.025)
    assert prof.arc_m[-1] == distance and prof.arc_m.max() <= distance + 1e-9
    t = np.arange(0.0, prof.duration_s, 0.001)
    s, v, a = np.array([prof.at(float(tk)) for tk in t]).T
    assert np.abs(v).max() <= lim.max_speed_mps * (1 + 1e-6)
    assert np.abs(a).max() <= lim.max_accel_mps2 * (1 + 1e-6)


def test_a_leg_of_no_length_at_rest_is_a_segment_of_no_duration() -> None:
    """A route that repeats a waypoint where the vehicle is at rest (a lane's flow timing on grid-256, stop 68: the
    weights were 0 / 0 and Ruckig got NaN limits): a segment of zero duration at that point, either synchronisation."""
    from proxplan.planner.timing.segments import through_segment

    for straight in (False, True):
        traj = through_segment([1.0, 2.0, 3.0], [1.0, 2.0, 3.0], [0.0] * 3, [0.0] * 3, KinematicLimits(1.0, 2.0, 8.0),
                               straight=straight)  # fmt: skip
        position, velocity, _ = traj.at_time(0.0)
        assert traj.duration == 0.0 and position == [1.0, 2.0, 3.0] and velocity == [0.0, 0.0, 0.0]
