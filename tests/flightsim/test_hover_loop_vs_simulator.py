"""The closed-loop model of a vehicle in a jet (proxplan.physics.hover_loop) is the loop the
simulator flies: its poles equal those of the simulator's own step (controller, motor lag, RotorPy
dynamics, RK4 at 500 Hz) linearised about the same hover with CasADi, in a jet and without one."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from proxplan.flightsim.mellinger import CONTROLLER_STATE_SIZE, controller_gains
from proxplan.flightsim.stepper import CompiledStepper
from proxplan.flightsim.vehicle_params import quad_params
from proxplan.physics import BUILTIN_VEHICLES, GRAVITY_MPS2, disturbance_wrench
from proxplan.physics.hover_loop import loop_matrices, loop_poles, wrench_gradient

DT_S = 0.002  # the simulator's physics step, s


def _simulator_poles(vehicle, force_N, torque_Nm, gf, gt) -> np.ndarray:
    """Continuous-time poles log(mu) / dt of the simulator's step linearised about the on-axis
    hover (position 0, level, rotors at the trim thrust, the z integrator holding the jet)."""
    params = quad_params(vehicle)
    gains = controller_gains(vehicle)
    step = CompiledStepper([params], DT_S, controllers=[gains]).function
    s = ca.SX.sym("s", 17)
    mem = ca.SX.sym("m", CONTROLLER_STATE_SIZE)
    f_ext = ca.DM(force_N) + ca.mtimes(ca.DM(gf), s[0:3])
    t_ext = ca.DM(torque_Nm) + ca.mtimes(ca.DM(gt), s[0:3])
    out = step(s, ca.DM.zeros(12), f_ext, t_ext, ca.DM.zeros(3), ca.DM.zeros(3), mem)
    z = ca.vertcat(s, mem)
    jac = ca.Function("step_jacobian", [z], [ca.jacobian(ca.vertcat(out[0], out[5]), z)])
    trim = vehicle.mass_kg * GRAVITY_MPS2 - force_N[2]
    z0 = np.zeros(17 + CONTROLLER_STATE_SIZE)
    z0[9] = 1.0  # level
    z0[13:17] = np.sqrt(trim / 4.0 / params["k_eta"])
    z0[17 + 2] = -force_N[2] / gains.ki_Npms[2]  # the z integrator holds the jet
    z0[17 + 8] = 1.0  # the rate-error difference is valid
    mu = np.linalg.eigvals(np.array(jac(z0)))
    mu = mu[np.abs(mu) > 1e-9]
    return np.log(mu.astype(complex)) / DT_S


def _slow(poles: np.ndarray) -> np.ndarray:
    """The poles slower than 30 1/s (where a 500 Hz step is continuous time), sorted."""
    p = poles[(np.abs(poles) < 30.0) & (np.abs(poles) > 1e-6)]
    return p[np.lexsort((p.imag, np.round(p.real, 4)))]


@pytest.mark.parametrize("dz_m", [None, 1.0, 1.1])
def test_model_poles_are_the_simulators(dz_m):
    src, tgt = BUILTIN_VEHICLES["large-quad"], BUILTIN_VEHICLES["small-quad"]
    if dz_m is None:
        force, torque, gf, gt = np.zeros(3), np.zeros(3), np.zeros((3, 3)), np.zeros((3, 3))
    else:

        def wrench(p):
            w = disturbance_wrench(src, tgt, p - np.array([0.0, 0.0, dz_m]))
            return w.force_N, w.torque_Nm

        force, torque = (x[0] for x in wrench(np.zeros((1, 3))))
        gf, gt = (x[0] for x in wrench_gradient(wrench, np.zeros((1, 3))))
    mats = loop_matrices(tgt, force[None], torque[None], gf[None], gt[None])
    model = _slow(np.linalg.eigvals(mats.a[0]))
    sim = _slow(_simulator_poles(tgt, force, torque, gf, gt))
    # every slow pole of the simulator has a model pole within 0.01 1/s + 3 % (the 500 Hz step and the
    # controller's rate-error difference move the 10-20 1/s poles by ~1.5 %; the loop's slow poles
    # agree to 0.003 1/s)
    for p in sim:
        assert np.min(np.abs(model - p)) < 0.01 + 0.03 * abs(p), (p, model)
    if dz_m is not None:  # and the rightmost one (the loop's verdict) agrees to 0.01 1/s
        top_sim = sim[np.argmax(sim.real)]
        assert abs(loop_poles(mats).growth_ps[0] - top_sim.real) < 0.01
