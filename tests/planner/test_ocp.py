"""Tests of proxplan.planner.optimizer.ocp: the CasADi trajectory problem.

The wrench table here is a small casadi bspline interpolant built from proxplan.physics.disturbance on a
coarse grid (tests only); the product uses proxplan.costmaps.map_store's table of the same numbers.
"""

from __future__ import annotations

import casadi
import numpy as np
import pytest

from proxplan.physics import (
    BUILTIN_VEHICLES,
    authority_usage,
    disturbance_wrench,
    normalised_motor_map,
)
from proxplan.planner.optimizer.ocp import build_and_solve, sample_solution
from proxplan.planner.optimizer.ocp_problem import OcpAgent, OcpProblem, OcpSolution

LARGE = BUILTIN_VEHICLES["large-quad"]
SMALL = BUILTIN_VEHICLES["small-quad"]


def model_interpolant(source, target, *, half_width_m=1.5, dz_min_m=-0.4, dz_max_m=2.5, step_m=0.1):
    """casadi bspline of (F_z N, tau_x N m, tau_y N m) over offsets p_target - p_source (3,), m,
    on a grid x, y in [-w, w] and offset_z in [-dz_max, -dz_min], from proxplan.physics.disturbance."""
    gxy = np.arange(-half_width_m, half_width_m + 1e-9, step_m)
    gz = np.arange(-dz_max_m, -dz_min_m + 1e-9, step_m)
    X, Y, Z = np.meshgrid(gxy, gxy, gz, indexing="ij")
    offsets = np.column_stack([X.ravel(order="F"), Y.ravel(order="F"), Z.ravel(order="F")])
    w = disturbance_wrench(source, target, offsets)
    values = np.column_stack([w.force_N[:, 2], w.torque_Nm[:, 0], w.torque_Nm[:, 1]])
    return casadi.interpolant("wrench", "bspline", [gxy, gxy, gz], values.ravel())


def _quintic(start, goal, n):
    s = np.linspace(0.0, 1.0, n + 1)
    sm = 10 * s**3 - 15 * s**4 + 6 * s**5
    return start + (goal - start) * sm[:, None]


def test_normalised_motor_map_reproduces_authority_usage():
    rng = np.random.default_rng(1)
    force = np.zeros((50, 3))
    force[:, 2] = rng.uniform(-1.0, 1.0, 50)
    torque = np.zeros((50, 3))
    torque[:, :2] = rng.uniform(-0.05, 0.05, (50, 2))
    for vehicle in (SMALL, LARGE):
        a_map, up, down = normalised_motor_map(vehicle)
        delta = (a_map @ np.column_stack([force[:, 2], torque[:, 0], torque[:, 1]]).T).T
        usage = np.maximum((delta / up).max(axis=1), (-delta / down).max(axis=1))
        np.testing.assert_allclose(usage, authority_usage(vehicle, force, torque), rtol=1e-9, atol=1e-12)


def test_sample_solution_is_exact_piecewise_constant_jerk():
    rng = np.random.default_rng(2)
    n, T = 8, 4.0
    h = T / n
    jerk = rng.normal(size=(n, 3))
    p, v, a = np.zeros((n + 1, 3)), np.zeros((n + 1, 3)), np.zeros((n + 1, 3))
    p[0] = [1.0, 2.0, 3.0]
    for k in range(n):
        j = jerk[k]
        p[k + 1] = p[k] + h * v[k] + h**2 / 2 * a[k] + h**3 / 6 * j
        v[k + 1] = v[k] + h * a[k] + h**2 / 2 * j
        a[k + 1] = a[k] + h * j
    sol = OcpSolution(True, "ok", T, {"x": p}, {"x": v}, {"x": a}, {"x": jerk}, 0, 0.0, 0.0, 0.0)
    t = np.linspace(0.0, T, 801)
    ps, vs, as_ = sample_solution(sol, t)["x"]
    np.testing.assert_allclose(ps[::100], p, atol=1e-12)
    dt = t[1] - t[0]
    np.testing.assert_allclose(np.gradient(ps, dt, axis=0)[1:-1], vs[1:-1], atol=5e-3)
    np.testing.assert_allclose(np.gradient(vs, dt, axis=0)[1:-1], as_[1:-1], atol=5e-2 * np.abs(jerk).max())
    # slowing down by s stretches time and scales velocity by 1 / s
    ps2, vs2, _ = sample_solution(sol, 2.0 * t, time_scale=2.0)["x"]
    np.testing.assert_allclose(ps2, ps, atol=1e-12)
    np.testing.assert_allclose(vs2, vs / 2.0, atol=1e-12)


def _single_agent(start, goal, n, warm=None, **kw):
    return OcpAgent(
        name="a",
        vehicle=SMALL,
        moving=True,
        start_m=start,
        goal_m=goal,
        max_speed_mps=1.0,
        max_accel_mps2=2.0,
        max_jerk_mps3=10.0,
        body_radius_m=0.1,
        warm_position_m=_quintic(start, goal, n) if warm is None else warm,
        **kw,
    )


def test_single_vehicle_around_obstacle_respects_limits_and_boundary_conditions():
    n, T0 = 30, 8.0
    start, goal = np.array([-1.5, 0.0, 1.0]), np.array([1.5, 0.0, 1.0])
    box = (np.array([-0.3, -0.3, 0.0]), np.array([0.3, 0.25, 2.0]))
    # collision-free warm start (as the sampling planner gives): a detour on the +y side
    s = np.linspace(0.0, 1.0, n + 1)
    warm = start + (goal - start) * s[:, None]
    warm[:, 1] = 0.8 * np.sin(np.pi * s)
    problem = OcpProblem(
        agents=(_single_agent(start, goal, n, warm=warm),),
        n_intervals=n,
        warm_duration_s=T0,
        max_duration_s=T0,
        workspace_min_m=np.array([-3.0, -3.0, 0.0]),
        workspace_max_m=np.array([3.0, 3.0, 3.0]),
        obstacles=(box,),
    )
    sol = build_and_solve(problem)
    assert sol.success, sol.status
    assert sol.duration_s < T0  # shorter than the slow warm start
    # a 3 m flight at 1 m/s with 2 m/s^2 cannot take less than 3 s
    assert sol.duration_s > 3.0
    np.testing.assert_allclose(sol.position_m["a"][0], start, atol=1e-6)
    np.testing.assert_allclose(sol.position_m["a"][-1], goal, atol=1e-6)
    np.testing.assert_allclose(sol.velocity_mps["a"][[0, -1]], 0.0, atol=1e-6)
    t = np.linspace(0.0, sol.duration_s, 600)
    p, v, a = sample_solution(sol, t)["a"]
    assert np.abs(v).max() <= 1.0 + 1e-6
    assert np.abs(a).max() <= 2.0 + 1e-6
    assert np.abs(sol.jerk_mps3["a"]).max() <= 10.0 + 1e-6
    inflated_lo, inflated_hi = box[0] - 0.1, box[1] + 0.1
    inside = np.all((p > inflated_lo) & (p < inflated_hi), axis=1)
    assert not inside.any()


@pytest.mark.parametrize("linearize", [False, True])
def test_authority_constraint_keeps_target_out_of_the_jet(linearize):
    """A small quad crossing 1.2 m below a hovering large quad must bend its path out of the jet,
    with the exact table (MX) and with its sequential linearisation (SX). The linearised model needs
    a lateral gradient at the warm start, so its warm path is 0.1 m off the jet axis (still inside)."""
    n, T0 = 30, 8.0
    source_pos = np.array([0.0, 0.0, 2.4])
    start, goal = np.array([-1.2, 0.0, 1.2]), np.array([1.2, 0.0, 1.2])
    fraction = 0.07
    table = model_interpolant(LARGE, SMALL, dz_min_m=0.5, dz_max_m=1.9)
    warm = _quintic(start, goal, n)
    warm[:, 1] += 0.1 * np.sin(np.linspace(0.0, np.pi, n + 1)) if linearize else 0.0
    agents = (
        OcpAgent(name="src", vehicle=LARGE, moving=False, start_m=source_pos, body_radius_m=0.27),
        _single_agent(start, goal, n, warm=warm),
    )
    base = dict(
        linearize=linearize,
        n_intervals=n,
        warm_duration_s=T0,
        max_duration_s=T0,
        workspace_min_m=np.array([-3.0, -3.0, 0.0]),
        workspace_max_m=np.array([3.0, 3.0, 3.0]),
        authority_fraction=fraction,
    )
    straight = disturbance_wrench(LARGE, SMALL, warm - source_pos)
    assert authority_usage(SMALL, straight.force_N, straight.torque_Nm).max() > 2 * fraction
    sol = build_and_solve(OcpProblem(agents=agents, wrench_functions={("src", "a"): table}, **base))
    assert sol.success, sol.status
    t = np.linspace(0.0, sol.duration_s, 400)
    p = sample_solution(sol, t)["a"][0]
    w = disturbance_wrench(LARGE, SMALL, p - source_pos)
    usage = authority_usage(SMALL, w.force_N, w.torque_Nm)
    assert usage.max() <= fraction * 1.02  # the model itself, between nodes too
    lateral = np.linalg.norm(p[:, 1:] - np.array([0.0, 1.2]), axis=1)
    assert lateral[np.abs(p[:, 0]) < 0.1].min() > 0.1  # it bends away from the jet's axis
    # without the table the optimiser cuts straight through the jet
    free = build_and_solve(OcpProblem(agents=agents, **base))
    p_free = sample_solution(free, t * free.duration_s / sol.duration_s)["a"][0]
    w_free = disturbance_wrench(LARGE, SMALL, p_free - source_pos)
    assert authority_usage(SMALL, w_free.force_N, w_free.torque_Nm).max() > fraction
    assert free.duration_s <= sol.duration_s + 1e-6


def test_dock_to_moving_partner_and_infeasible_authority_fails():
    n, T0 = 24, 8.0
    carrier_start, carrier_goal = np.array([0.0, 0.0, 1.0]), np.array([0.5, 0.0, 1.0])
    shuttle_start = np.array([1.5, 1.0, 2.2])
    offset = np.array([0.0, 0.0, 0.5])
    carrier = OcpAgent(
        name="carrier",
        vehicle=LARGE,
        moving=True,
        start_m=carrier_start,
        goal_m=carrier_goal,
        body_radius_m=0.27,
        warm_position_m=_quintic(carrier_start, carrier_goal, n),
    )
    shuttle = OcpAgent(
        name="shuttle",
        vehicle=SMALL,
        moving=True,
        start_m=shuttle_start,
        dock_with="carrier",
        dock_offset_m=offset,
        body_radius_m=0.09,
        warm_position_m=_quintic(shuttle_start, carrier_goal + offset, n),
    )
    table = model_interpolant(SMALL, LARGE, half_width_m=1.0, dz_min_m=0.2, dz_max_m=1.4, step_m=0.1)
    base = dict(
        agents=(carrier, shuttle),
        n_intervals=n,
        warm_duration_s=T0,
        max_duration_s=T0,
        workspace_min_m=np.array([-3.0, -3.0, 0.0]),
        workspace_max_m=np.array([3.0, 3.0, 3.0]),
        wrench_functions={("shuttle", "carrier"): table},
    )
    sol = build_and_solve(OcpProblem(authority_fraction=0.5, **base))
    assert sol.success, sol.status
    np.testing.assert_allclose(sol.position_m["carrier"][-1], carrier_goal, atol=1e-6)
    np.testing.assert_allclose(sol.position_m["shuttle"][-1], carrier_goal + offset, atol=1e-6)
    # the docked configuration itself needs more than 0.001 of the carrier's authority
    docked = disturbance_wrench(SMALL, LARGE, -offset)
    assert authority_usage(LARGE, docked.force_N, docked.torque_Nm)[0] > 0.001
    bad = build_and_solve(OcpProblem(authority_fraction=0.001, max_iterations=100, **base))
    assert not bad.success
    assert bad.status != "Solve_Succeeded"


def test_warm_start_repair_moves_a_path_out_of_the_jet_and_keeps_its_ends():
    """A warm path straight along the symmetric jet axis is a saddle for IPOPT; the repair displaces
    it sideways until the predicted usage is under the limit, without touching start and goal."""
    from proxplan.planner.optimizer.ocp_warm import repair_warm_start

    n = 30
    source_pos = np.array([0.0, 0.0, 2.4])
    start, goal = np.array([-1.2, 0.0, 1.2]), np.array([1.2, 0.0, 1.2])
    table = model_interpolant(LARGE, SMALL, dz_min_m=0.5, dz_max_m=1.9)
    agents = (
        OcpAgent(name="src", vehicle=LARGE, moving=False, start_m=source_pos, body_radius_m=0.27),
        _single_agent(start, goal, n),
    )
    problem = OcpProblem(agents=agents, n_intervals=n, warm_duration_s=8.0, max_duration_s=8.0,
                         workspace_min_m=np.array([-3.0, -3.0, 0.0]), workspace_max_m=np.array([3.0, 3.0, 3.0]),
                         authority_fraction=0.07, wrench_functions={("src", "a"): table})  # fmt: skip
    repaired, moved = repair_warm_start(problem)
    assert moved > 0
    warm = repaired.agents[1].warm_position_m
    np.testing.assert_allclose(warm[[0, -1]], [start, goal])
    w = disturbance_wrench(LARGE, SMALL, warm - source_pos)
    assert authority_usage(SMALL, w.force_N, w.torque_Nm).max() <= 0.07
    assert np.ptp(warm[:, 2]) < 1e-12  # moved horizontally only
    again, moved_again = repair_warm_start(repaired)
    assert moved_again == 0 and again is repaired  # nothing left to repair
