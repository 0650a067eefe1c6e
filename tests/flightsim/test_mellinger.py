"""The firmware-like Mellinger controller: rate feed-forward, hover and step sanity, reference body
rates, the firmware's motor cap."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.flightsim import SimulationOptions, simulate_plan
from proxplan.flightsim.mellinger import controller_gains, reference_body_rates
from proxplan.flightsim.scenarios_synthetic import single_hover_plan
from proxplan.physics import BUILTIN_VEHICLES, KinematicLimits, cap_motor_thrusts
from proxplan.planfile import Plan, VehicleTrajectory
from proxplan.planner import common_grid, time_parameterize

QUIET = SimulationOptions(imu_noise=False, settle_s=0.5)


def _segment_plan(vehicle, limits: KinematicLimits, length_m: float = 1.0) -> Plan:
    """Rest-to-rest horizontal segment, Ruckig-timed at ``limits``."""
    pts = np.array([[0.0, 0.0, 1.0], [length_m, 0.0, 1.0]])
    timed = time_parameterize(pts, None, limits)
    t = common_grid(timed.duration_s, 0.05)
    p, v, a = timed.sample(t)
    return Plan("segment", 0.05, {"v": VehicleTrajectory("v", vehicle.name, vehicle, t, p, v, a)})


def _max_error_m(plan: Plan, **kw) -> float:
    rec = simulate_plan(plan, options=SimulationOptions(imu_noise=False, settle_s=0.5, **kw)).records["v"]
    return float(np.linalg.norm(rec.position_m - rec.ref_position_m, axis=1).max())


def test_rate_feedforward_cuts_the_max_tracking_error_at_least_3x():
    """Fast jerk-limited segment (1.5 m/s, 2.5 m/s^2, 10 m/s^3): without the body-rate feed-forward
    the firmware's soft attitude loop lags; with it the error is several times smaller."""
    plan = _segment_plan(BUILTIN_VEHICLES["crazyflie-2.1"], KinematicLimits(1.5, 2.5, 10.0))
    with_ff = _max_error_m(plan)
    without = _max_error_m(plan, rate_feedforward=False)
    assert without > 4.0 * with_ff, (with_ff, without)  # measured ~9x; the issue asks >= 3x


@pytest.mark.parametrize("name", ["crazyflie-2.1", "large-quad"])
def test_hover_holds_position_with_equal_motor_thrusts(name):
    plan = single_hover_plan(type_name=name, duration_s=2.0)
    res = simulate_plan(plan, options=QUIET)
    for rec in res.records.values():
        err = np.linalg.norm(rec.position_m - rec.ref_position_m, axis=1)
        assert err.max() < 1e-3
        hover = rec.vehicle.hover_thrust_per_rotor_N
        np.testing.assert_allclose(rec.motor_thrust_N[-1], hover, rtol=1e-3)


def test_position_step_settles_without_large_overshoot():
    """A 0.2 m reference step in x (nothing to feed forward): the firmware's position loop (kp 0.4
    N/m, kd 0.2 N s/m, ki 0.05 N/(m s) on 32 g) behind its attitude loop, whose slow pole sits at
    kR/kw = 3.5 1/s, overshoots by about 20 % and creeps in on its integrator (measured: 7.5 mm off
    after 7 s)."""
    veh = BUILTIN_VEHICLES["crazyflie-2.1"]
    t = np.arange(0.0, 8.0 + 1e-9, 0.05)
    p = np.tile([0.2, 0.0, 1.0], (t.size, 1))
    plan = Plan("step", 0.05, {"v": VehicleTrajectory("v", veh.name, veh, t, p, np.zeros_like(p), np.zeros_like(p))})
    res = simulate_plan(plan, options=QUIET, perturbation=_start_offset(-0.2))
    rec = res.records["v"]
    x = rec.position_m[:, 0]
    assert x.max() < 0.2 + 0.35 * 0.2
    assert abs(x[rec.t_s >= 6.0] - 0.2).max() < 0.015
    assert abs(rec.position_m[:, 1:] - [0.0, 1.0]).max() < 0.005  # the other axes stay put


def _start_offset(dx_m: float):
    from proxplan.flightsim import Perturbation

    return Perturbation(start_offset_m={"v": (dx_m, 0.0, 0.0)})


def test_reference_body_rates_turn_the_thrust_axis_as_the_reference_does():
    """w x z_B = dz_B/dt for z_B = (a + g)/|a + g| along a smooth acceleration history."""
    t = np.linspace(0.0, 2.0, 2001)
    acc = np.column_stack([3.0 * np.sin(2.0 * t), 2.0 * np.cos(3.0 * t), 1.0 * np.sin(t)])
    jerk = np.column_stack([6.0 * np.cos(2.0 * t), -6.0 * np.sin(3.0 * t), np.cos(t)])
    w = reference_body_rates(acc, jerk)
    thrust = acc + [0.0, 0.0, 9.81]
    zb = thrust / np.linalg.norm(thrust, axis=1, keepdims=True)
    yb = np.cross(zb, [1.0, 0.0, 0.0])
    yb /= np.linalg.norm(yb, axis=1, keepdims=True)
    xb = np.cross(yb, zb)
    rot = np.stack([xb, yb, zb], axis=2)  # body to world
    w_world = np.einsum("kij,kj->ki", rot, w)
    dz = np.gradient(zb, t, axis=0)
    inner = slice(5, -5)
    np.testing.assert_allclose(np.cross(w_world, zb)[inner], dz[inner], atol=2e-4)
    assert np.abs(w).max() > 0.3  # a real rotation, not a trivially zero answer


def test_motor_cap_lowers_every_motor_by_the_excess_then_floors():
    out = [float(f) for f in cap_motor_thrusts([0.20, 0.10, 0.05, -0.01], 0.15, 0.0)]
    np.testing.assert_allclose(out, [0.15, 0.05, 0.0, 0.0])
    same = [float(f) for f in cap_motor_thrusts([0.1, 0.1, 0.12, 0.02], 0.15, 0.0)]
    np.testing.assert_allclose(same, [0.1, 0.1, 0.12, 0.02])


def test_gains_firmware_for_crazyflies_scaled_for_other_types():
    cf = controller_gains(BUILTIN_VEHICLES["crazyflie-2.1"])
    assert cf.kp_Npm == (0.4, 0.4, 1.25)  # controller_mellinger.c kp_xy, kp_z in N/m
    # kR_xy = 70000 PWM/rad -> N m/rad through massThrust = 132000 and the arm offset l/sqrt2
    np.testing.assert_allclose(cf.kR_Nmprad[0], 70000 * 2 * 0.046 / np.sqrt(2) / (4 * 132000))
    for name, v in BUILTIN_VEHICLES.items():
        g = controller_gains(v)
        if name == "crazyflie-2.1":
            assert g.kp_Npm == cf.kp_Npm
        else:  # same closed-loop poles: gain per kg and per kg m^2 as the Crazyflie's
            np.testing.assert_allclose(np.array(g.kp_Npm) / v.mass_kg, np.array(cf.kp_Npm) / 0.032)
            np.testing.assert_allclose(
                np.array(g.kR_Nmprad) / np.array(v.inertia_diag_kgm2),
                np.array(cf.kR_Nmprad) / np.array(BUILTIN_VEHICLES["crazyflie-2.1"].inertia_diag_kgm2),
            )


def test_rotorpy_controller_stays_available_and_differs():
    plan = _segment_plan(BUILTIN_VEHICLES["crazyflie-2.1"], KinematicLimits(1.0, 1.0, 2.0))
    a = _max_error_m(plan)
    b = _max_error_m(plan, controller="rotorpy")
    assert a != b and np.isfinite(b)
