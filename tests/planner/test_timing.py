"""Ruckig timing: chained rest-to-rest segments respect the norm limits, the schedule and the path."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.physics import KinematicLimits
from proxplan.planner.timing import (
    common_grid,
    min_segment_duration_s,
    ruckig_segment,
    time_parameterize,
)

LIMITS = KinematicLimits(max_speed_mps=1.2, max_accel_mps2=2.5, max_jerk_mps3=12.0)


def _sampled(tp, dt=0.005):
    t = common_grid(tp.duration_s, dt)
    return t, *tp.sample(t)


def test_norm_limits_hold_on_diagonal_segments():
    pts = np.array([[0, 0, 1], [1.5, 1.5, 2.0], [1.5, 1.5, 2.0], [-1, 2, 1]], dtype=float)
    tp = time_parameterize(pts, None, LIMITS)
    t, p, v, a = _sampled(tp)
    assert np.linalg.norm(v, axis=1).max() <= LIMITS.max_speed_mps * (1 + 1e-6)
    assert np.linalg.norm(a, axis=1).max() <= LIMITS.max_accel_mps2 * (1 + 1e-6)
    jerk = np.linalg.norm(np.diff(a, axis=0), axis=1) / np.diff(t)
    assert np.percentile(jerk, 99) <= LIMITS.max_jerk_mps3 * 1.05
    np.testing.assert_allclose(p[-1], pts[-1], atol=1e-9)


def test_segments_are_straight_and_end_at_rest():
    pts = np.array([[0, 0, 1], [2.0, -1.0, 1.5], [0.5, 0.5, 0.5]])
    tp = time_parameterize(pts, None, LIMITS)
    t, p, v, _ = _sampled(tp)
    for k in range(2):
        inside = (t > tp.knot_t_s[k]) & (t < tp.knot_t_s[k + 1])
        d = pts[k + 1] - pts[k]
        rel = p[inside] - pts[k]
        off_line = np.linalg.norm(np.cross(rel, d / np.linalg.norm(d)), axis=1)
        assert off_line.max() < 1e-6  # phase synchronisation keeps the segment straight
        at_knot = np.argmin(np.abs(t - tp.knot_t_s[k + 1]))
        assert np.linalg.norm(v[at_knot]) < 0.05


def test_schedule_is_met_and_never_shortened():
    pts = np.array([[0, 0, 1], [1, 0, 1], [1, 0, 1], [1, 1, 1]], dtype=float)
    sched = np.array([0.0, 3.0, 5.0, 6.0])  # the last hop is too short: pushed back
    tp = time_parameterize(pts, sched, LIMITS)
    assert tp.knot_t_s[1] == pytest.approx(3.0, abs=1e-6)
    assert tp.knot_t_s[2] == pytest.approx(5.0, abs=1e-6)  # a wait is a hold
    assert tp.knot_t_s[3] >= 5.0 + min_segment_duration_s(1.0, LIMITS) - 1e-3
    _, p, _, _ = _sampled(tp)
    t = common_grid(tp.duration_s, 0.005)
    hold = (t > 3.0 + 1e-6) & (t < 5.0 - 1e-6)
    np.testing.assert_allclose(p[hold], np.repeat(pts[1][None], hold.sum(), axis=0), atol=1e-9)


@pytest.mark.parametrize("distance_m", [0.003, 0.05, 0.4, 1.0, 3.7, 12.0])
def test_duration_table_never_below_ruckig_optimum(distance_m):
    direction = np.array([0.6, -0.48, 0.64])
    optimum = ruckig_segment(np.zeros(3), distance_m * direction, LIMITS).duration
    bound = min_segment_duration_s(distance_m, LIMITS)
    assert optimum <= bound + 1e-9
    if distance_m >= 0.05:
        assert bound <= optimum * 1.05 + 0.02  # and tight: tabulated every 1 cm
    stretched = ruckig_segment(np.zeros(3), distance_m * direction, LIMITS, minimum_duration_s=bound)
    assert stretched.duration == pytest.approx(bound, abs=1e-6)


def test_common_grid_covers_the_end():
    g = common_grid(1.23, 0.05)
    assert g[0] == 0 and g[-1] >= 1.23 and g[-2] < 1.23
    np.testing.assert_allclose(np.diff(g), 0.05)
