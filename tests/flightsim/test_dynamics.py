"""The scalar/compiled dynamics, controller and IMU reproduce RotorPy's own classes."""

from __future__ import annotations

import numpy as np
import pytest
from rotorpy.controllers.quadrotor_control import SE3Control
from rotorpy.sensors.imu import Imu
from rotorpy.vehicles.multirotor import Multirotor

from proxplan.flightsim.control import ControllerConstants, se3_control
from proxplan.flightsim.dynamics import ExternalWrenchMultirotor, VehicleConstants, state_derivative
from proxplan.flightsim.imu import ImuOptions, imu_samples
from proxplan.flightsim.stepper import CompiledStepper
from proxplan.flightsim.vehicle_params import quad_params
from proxplan.physics import BUILTIN_VEHICLES, mixer_matrix

NAMES = ["crazyflie-2.1", "large-quad"]


def _random_state(rng):
    q = rng.normal(size=4) * [0.1, 0.1, 0.3, 1.0]
    q /= np.linalg.norm(q)
    return np.concatenate(
        [rng.normal(size=3), rng.normal(size=3), q, rng.normal(size=3), rng.uniform(400, 1800, size=4)]
    )


def _state_dict(s):
    return {"x": s[0:3], "v": s[3:6], "q": s[6:10], "w": s[10:13], "wind": np.zeros(3), "rotor_speeds": s[13:17]}


@pytest.mark.parametrize("name", NAMES)
def test_state_derivative_equals_rotorpy_with_external_wrench(name):
    rng = np.random.default_rng(1)
    p = quad_params(BUILTIN_VEHICLES[name])
    s = _random_state(rng)
    cmd = rng.uniform(300, 1500, size=4)
    f_ext = rng.normal(size=3) * 0.1
    t_ext = rng.normal(size=3) * 1e-3
    ours = np.array(state_derivative(VehicleConstants.from_params(p), list(s), list(cmd), list(f_ext), list(t_ext)))
    ref = ExternalWrenchMultirotor(p, aero=True)
    ref.ext_force_N = f_ext
    ref.ext_torque_Nm = t_ext
    sd = ref._s_dot_fn(0.0, Multirotor._pack_state(_state_dict(s)), cmd)
    expected = np.concatenate([sd[0:13], sd[16:20]])  # drop RotorPy's (zero) wind derivative
    np.testing.assert_allclose(ours, expected, rtol=1e-9, atol=1e-9)


def test_motor_numbering_maps_to_s0_14_mixer():
    """RotorPy's allocation with our quad_params equals the costmaps (S0-14) mixer."""
    for name in NAMES:
        veh = BUILTIN_VEHICLES[name]
        np.testing.assert_allclose(SE3Control(quad_params(veh)).f_to_TM, mixer_matrix(veh), rtol=1e-12, atol=1e-15)


@pytest.mark.parametrize("name", NAMES)
def test_controller_equals_rotorpy_se3control(name):
    rng = np.random.default_rng(3)
    p = quad_params(BUILTIN_VEHICLES[name])
    s = _random_state(rng)
    s[0:6] *= 0.1
    ref_x, ref_v, ref_a = (rng.normal(size=3) * sc for sc in (0.1, 0.1, 0.5))
    speeds, thrusts, u1, u2 = se3_control(ControllerConstants.from_params(p), list(s), ref_x, ref_v, ref_a)
    flat = {
        "x": ref_x,
        "x_dot": ref_v,
        "x_ddot": ref_a,
        "x_dddot": np.zeros(3),
        "x_ddddot": np.zeros(3),
        "yaw": 0.0,
        "yaw_dot": 0.0,
    }
    ref = SE3Control(p).update(0.0, _state_dict(s), flat)
    np.testing.assert_allclose(u1, ref["cmd_thrust"], rtol=1e-10)
    np.testing.assert_allclose(u2, ref["cmd_moment"], rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(speeds, ref["cmd_motor_speeds"], rtol=1e-8)
    np.testing.assert_allclose(thrusts, ref["cmd_motor_thrusts"], rtol=1e-8, atol=1e-12)


def test_compiled_step_matches_rotorpy_controller_and_step():
    rng = np.random.default_rng(4)
    params = [quad_params(BUILTIN_VEHICLES[n]) for n in NAMES]
    dt = 0.002
    stepper = CompiledStepper(params, dt)
    for i in range(len(params)):
        s = _random_state(rng)
        s[0:6] *= 0.05
        s[10:13] *= 0.1
        stepper.state[i] = s
        stepper.ref[i] = np.concatenate([rng.normal(size=3) * 0.05, np.zeros(9)])
        stepper.ext_force_N[i] = rng.normal(size=3) * 0.01
        stepper.ext_torque_Nm[i] = rng.normal(size=3) * 1e-4
    stepper.step()
    for i, p in enumerate(params):
        s = stepper.state[i]
        flat = {
            "x": stepper.ref[i, 0:3],
            "x_dot": stepper.ref[i, 3:6],
            "x_ddot": stepper.ref[i, 6:9],
            "x_dddot": np.zeros(3),
            "x_ddddot": np.zeros(3),
            "yaw": 0.0,
            "yaw_dot": 0.0,
        }
        ctrl = SE3Control(p).update(0.0, _state_dict(s), flat)
        ref = ExternalWrenchMultirotor(p, aero=True, integrator_kwargs={"method": "RK45", "rtol": 1e-10, "atol": 1e-12})
        ref.ext_force_N = stepper.ext_force_N[i]
        from scipy.spatial.transform import Rotation

        ref.ext_torque_Nm = Rotation.from_quat(s[6:10]).inv().apply(stepper.ext_torque_Nm[i])
        out = ref.step(_state_dict(s.copy()), {"cmd_motor_speeds": ctrl["cmd_motor_speeds"]}, dt)
        nxt = stepper.next_state[i]
        np.testing.assert_allclose(nxt[0:3], out["x"], atol=1e-9)
        np.testing.assert_allclose(nxt[3:6], out["v"], atol=1e-7)
        np.testing.assert_allclose(nxt[6:10], out["q"], atol=1e-7)
        np.testing.assert_allclose(nxt[10:13], out["w"], atol=1e-5)
        np.testing.assert_allclose(nxt[13:17], out["rotor_speeds"], rtol=1e-7)
        np.testing.assert_allclose(stepper.cmd_thrust_N[i], ctrl["cmd_motor_thrusts"], rtol=1e-8, atol=1e-12)


def test_compiled_step_flags_and_clips_saturated_motors():
    p = quad_params(BUILTIN_VEHICLES["crazyflie-2.1"])
    stepper = CompiledStepper([p], 0.002)
    stepper.state[0, 9] = 1.0
    stepper.state[0, 13:17] = 1500.0
    stepper.ref[0, 0:3] = [0.0, 0.0, 10.0]  # 10 m below the reference: full throttle wanted
    stepper.step()
    assert stepper.saturated[0] == 1.0
    assert np.all(stepper.cmd_thrust_N[0] > BUILTIN_VEHICLES["crazyflie-2.1"].max_thrust_per_rotor_N)
    # rotor speeds move toward the clipped command, never beyond the limit
    assert np.all(stepper.next_state[0, 13:17] <= p["rotor_speed_max"] + 1e-9)
    stepper.ref[0, 0:3] = 0.0
    stepper.step()
    assert stepper.saturated[0] == 0.0


@pytest.mark.parametrize("name", NAMES)
def test_hover_rotor_speeds_hold_hover(name):
    veh = BUILTIN_VEHICLES[name]
    p = quad_params(veh)
    omega = np.sqrt(veh.hover_thrust_per_rotor_N / p["k_eta"])
    s = np.zeros(17)
    s[9] = 1.0
    s[13:17] = omega
    d = np.array(state_derivative(VehicleConstants.from_params(p), list(s), [omega] * 4, [0, 0, 0], [0, 0, 0]))
    np.testing.assert_allclose(d, 0.0, atol=1e-9)


def test_imu_equations_equal_rotorpy_imu_without_noise():
    rng = np.random.default_rng(5)
    q = rng.normal(size=(6, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    w = rng.normal(size=(6, 3))
    a = rng.normal(size=(6, 3))
    acc, gyr = imu_samples(q, w, a, options=ImuOptions(), with_noise=False)
    imu = Imu(sampling_rate=100)
    for k in range(6):
        out = imu.measurement(
            {"x": np.zeros(3), "v": np.zeros(3), "q": q[k], "w": w[k]},
            {"vdot": a[k], "wdot": np.zeros(3)},
            with_noise=False,
        )
        np.testing.assert_allclose(acc[k], out["accel"], atol=1e-12)
        np.testing.assert_allclose(gyr[k], out["gyro"], atol=1e-12)
    # noise has the configured spread
    acc_n, _ = imu_samples(
        np.tile([0, 0, 0, 1.0], (4000, 1)),
        np.zeros((4000, 3)),
        np.zeros((4000, 3)),
        options=ImuOptions(accel_noise_std_mps2=0.1),
        rng=np.random.default_rng(0),
    )
    np.testing.assert_allclose(acc_n.mean(axis=0), [0, 0, 9.81], atol=0.01)
    np.testing.assert_allclose(acc_n.std(axis=0), 0.1, rtol=0.1)
