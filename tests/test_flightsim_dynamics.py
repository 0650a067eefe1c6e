"""The vectorised dynamics and controller reproduce RotorPy's own Multirotor and SE3Control."""

from __future__ import annotations

import numpy as np
import pytest
from rotorpy.controllers.quadrotor_control import SE3Control
from rotorpy.vehicles.multirotor import Multirotor

from costmaps.builtin_vehicles import BUILTIN_VEHICLES
from costmaps.authority import mixer_matrix
from flightsim.control import BatchSE3Control
from flightsim.dynamics import BatchDynamics, BatchState, ExternalWrenchMultirotor
from flightsim.vehicle_params import quad_params

NAMES = ["crazyflie-2.1", "large-quad"]


def _random_state(rng, n):
    q = rng.normal(size=(n, 4)) * [0.1, 0.1, 0.3, 1.0]
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return BatchState(
        x=rng.normal(size=(n, 3)),
        v=rng.normal(size=(n, 3)),
        q=q,
        w=rng.normal(size=(n, 3)),
        rotor_speeds=rng.uniform(400, 1800, size=(n, 4)),
    )


def _state_dict(st, i):
    return {
        "x": st.x[i], "v": st.v[i], "q": st.q[i], "w": st.w[i],
        "wind": np.zeros(3), "rotor_speeds": st.rotor_speeds[i],
    }


def test_batch_derivative_equals_rotorpy_with_external_wrench():
    rng = np.random.default_rng(1)
    params = [quad_params(BUILTIN_VEHICLES[n]) for n in NAMES]
    dyn = BatchDynamics(params)
    st = _random_state(rng, 2)
    cmd = rng.uniform(300, 1500, size=(2, 4))
    f_ext = rng.normal(size=(2, 3)) * 0.1
    t_ext = rng.normal(size=(2, 3)) * 1e-3
    x_dot, v_dot, q_dot, w_dot, r_dot = dyn.derivative(st, cmd, f_ext, t_ext)
    for i, p in enumerate(params):
        ref = ExternalWrenchMultirotor(p, aero=True)
        ref.ext_force_N = f_ext[i]
        ref.ext_torque_Nm = t_ext[i]
        s = Multirotor._pack_state(_state_dict(st, i))
        sd = ref._s_dot_fn(0.0, s, cmd[i])
        np.testing.assert_allclose(x_dot[i], sd[0:3], rtol=1e-10)
        np.testing.assert_allclose(v_dot[i], sd[3:6], rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(q_dot[i], sd[6:10], rtol=1e-9, atol=1e-12)
        np.testing.assert_allclose(w_dot[i], sd[10:13], rtol=1e-8, atol=1e-8)
        np.testing.assert_allclose(r_dot[i], sd[16:20], rtol=1e-10)


def test_rk4_step_matches_rotorpy_step():
    rng = np.random.default_rng(2)
    p = quad_params(BUILTIN_VEHICLES["crazyflie-2.1"])
    dyn = BatchDynamics([p])
    st = _random_state(rng, 1)
    cmd = np.full((1, 4), 1800.0)
    f_ext = np.array([[0.0, 0.01, -0.02]])
    ref = ExternalWrenchMultirotor(p, aero=True, integrator_kwargs={"method": "RK45", "rtol": 1e-10, "atol": 1e-12})
    ref.ext_force_N = f_ext[0]
    out = ref.step(_state_dict(st, 0), {"cmd_motor_speeds": cmd[0]}, 0.002)
    new = dyn.rk4_step(st, cmd, f_ext, np.zeros((1, 3)), 0.002)
    np.testing.assert_allclose(new.x[0], out["x"], atol=1e-9)
    np.testing.assert_allclose(new.v[0], out["v"], atol=1e-7)
    np.testing.assert_allclose(new.q[0], out["q"], atol=1e-8)
    np.testing.assert_allclose(new.rotor_speeds[0], out["rotor_speeds"], rtol=1e-8)


def test_motor_numbering_maps_to_s0_14_mixer():
    """RotorPy's allocation with our quad_params equals the costmaps (S0-14) mixer."""
    for name in NAMES:
        veh = BUILTIN_VEHICLES[name]
        ctrl = SE3Control(quad_params(veh))
        ours = mixer_matrix(veh)  # rows T, tau_x, tau_y, tau_z
        np.testing.assert_allclose(ctrl.f_to_TM, ours, rtol=1e-12, atol=1e-15)


def test_batch_controller_equals_rotorpy_se3control():
    rng = np.random.default_rng(3)
    params = [quad_params(BUILTIN_VEHICLES[n]) for n in NAMES]
    ctrl = BatchSE3Control(params)
    st = _random_state(rng, 2)
    st.x *= 0.1
    st.v *= 0.1
    ref_x = rng.normal(size=(2, 3)) * 0.1
    ref_v = rng.normal(size=(2, 3)) * 0.1
    ref_a = rng.normal(size=(2, 3)) * 0.5
    out = ctrl.update(st, ref_x, ref_v, ref_a)
    for i, p in enumerate(params):
        flat = {"x": ref_x[i], "x_dot": ref_v[i], "x_ddot": ref_a[i], "x_dddot": np.zeros(3),
                "x_ddddot": np.zeros(3), "yaw": 0.0, "yaw_dot": 0.0}
        ref = SE3Control(p).update(0.0, _state_dict(st, i), flat)
        np.testing.assert_allclose(out.cmd_thrust_N[i], ref["cmd_thrust"], rtol=1e-10)
        np.testing.assert_allclose(out.cmd_moment_Nm[i], ref["cmd_moment"], rtol=1e-8, atol=1e-12)
        np.testing.assert_allclose(out.cmd_motor_speeds_radps[i], ref["cmd_motor_speeds"], rtol=1e-8)


@pytest.mark.parametrize("name", NAMES)
def test_hover_motor_speeds_hold_hover(name):
    veh = BUILTIN_VEHICLES[name]
    p = quad_params(veh)
    dyn = BatchDynamics([p])
    omega = np.sqrt(veh.hover_thrust_per_rotor_N / p["k_eta"])
    st = BatchState(np.zeros((1, 3)), np.zeros((1, 3)), np.array([[0, 0, 0, 1.0]]), np.zeros((1, 3)),
                    np.full((1, 4), omega))
    _, v_dot, _, w_dot, _ = dyn.derivative(st, st.rotor_speeds, np.zeros((1, 3)), np.zeros((1, 3)))
    np.testing.assert_allclose(v_dot, 0.0, atol=1e-9)
    np.testing.assert_allclose(w_dot, 0.0, atol=1e-9)
