"""Synthetic flights without the planner: boundary conditions and geometry."""

from __future__ import annotations

import numpy as np

from proxplan.flightsim import battery_swap_plans, hover_stack_plan, swap_plan, takeoff_hover_plan, waypoint_trajectory


def test_waypoint_trajectory_is_rest_to_rest_and_consistent():
    tr = waypoint_trajectory("a", "small-quad", [[0, 0, 1], [1, 2, 1.5], [1, 2, 1.5]], [0.0, 2.0, 3.0], dt_s=0.01)
    np.testing.assert_allclose(tr.position_m[0], [0, 0, 1])
    np.testing.assert_allclose(
        tr.position_m[tr.t_s >= 2.0], np.tile([1, 2, 1.5], ((tr.t_s >= 2.0).sum(), 1)), atol=1e-12
    )
    np.testing.assert_allclose(tr.velocity_mps[[0, -1]], 0.0)
    # velocity is the derivative of position, acceleration of velocity
    np.testing.assert_allclose(np.gradient(tr.position_m, tr.t_s, axis=0)[1:-1], tr.velocity_mps[1:-1], atol=2e-3)
    np.testing.assert_allclose(
        np.gradient(tr.velocity_mps, tr.t_s, axis=0)[5:195], tr.acceleration_mps2[5:195], atol=1e-2
    )
    # minimum-jerk peak speed 1.875 x mean speed
    np.testing.assert_allclose(np.linalg.norm(tr.velocity_mps, axis=1).max(), 1.875 * np.sqrt(5.25) / 2.0, rtol=1e-3)


def test_swap_plan_crosses_at_the_centre_with_the_vertical_gap():
    plan = swap_plan(vertical_gap_m=0.3, radius_m=0.25, swap_s=2.0, n_swaps=2, hold_s=1.0, centre_m=(0, 0, 1.0))
    top, bot = plan.vehicles["top"], plan.vehicles["bottom"]
    np.testing.assert_allclose(top.t_s, bot.t_s)
    gap = top.position_m[:, 2] - bot.position_m[:, 2]
    np.testing.assert_allclose(gap, 0.3)
    mid = np.argmin(np.abs(top.t_s - 2.0))  # halfway through the first swap (1 s pause, 2 s swap)
    np.testing.assert_allclose(top.position_m[mid, :2], 0.0, atol=1e-9)
    np.testing.assert_allclose(bot.position_m[mid, :2], 0.0, atol=1e-9)
    np.testing.assert_allclose(top.position_m[0, 0], 0.25)
    np.testing.assert_allclose(top.position_m[np.argmin(np.abs(top.t_s - 3.5)), 0], -0.25)
    assert top.t_s[-1] == 1.0 + 2 * (2.0 + 1.0)


def test_hover_stack_takeoff_and_battery_swap_helpers():
    st = hover_stack_plan(separation_m=1.5, horizontal_offset_m=(0.1, 0.0), bottom_position_m=(0, 0, 1))
    np.testing.assert_allclose(st.vehicles["bottom"].position_m[0] - st.vehicles["top"].position_m[0], [0.1, 0, -1.5])
    tk = takeoff_hover_plan(low_z_m=0.05, high_z_m=1.0, climb_s=2.0, hold_s=1.0)
    z = tk.vehicles["solo"].position_m[:, 2]
    assert abs(z.min() - 0.05) < 1e-12 and abs(z.max() - 1.0) < 1e-12
    plans = battery_swap_plans(duration_s=8.0)
    for p in plans.values():
        sh = p.vehicles["shuttle"]
        np.testing.assert_allclose(sh.position_m[-1], [0, 0, 1.8])
        assert sh.t_s[-1] == 8.0
    # the staged approach reaches the dock from directly above
    staged = plans["staged"].vehicles["shuttle"]
    late = staged.t_s > 5.0
    np.testing.assert_allclose(staged.position_m[late, :2], 0.0, atol=1e-12)
