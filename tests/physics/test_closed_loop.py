"""The linearised closed loop (proxplan.physics.closed_loop): the drag lead against its closed form,
lead and prediction as inverses, the deflection under a steady force, and the vehicle facts they
read (rotor drag and controller gains)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from proxplan.physics import (
    BUILTIN_VEHICLES,
    drag_lead,
    reference_error,
)

CF = BUILTIN_VEHICLES["crazyflie-2.1"]
NO_KI = dataclasses.replace(CF, controller=dataclasses.replace(CF.controller, ki_xy_Npms=0.0, ki_z_Npms=0.0))


def _cruise(speed_mps=(1.5, 0.0, 0.5), accel_s=1.0, total_s=12.0, step_s=0.01):
    """Accelerate uniformly for ``accel_s`` to ``speed_mps``, then cruise: (t, v, a, j), world frame."""
    t = np.arange(0.0, total_s, step_s)
    ramp = np.clip(t / accel_s, 0.0, 1.0)[:, None]
    v = ramp * np.asarray(speed_mps)[None]
    a = (t < accel_s)[:, None] * np.asarray(speed_mps)[None] / accel_s
    return t, v, a, np.zeros_like(v)


def test_drag_rate_is_four_rotors_of_rotorpy_drag_over_the_mass():
    # c = n omega_hover k_d / m (rotor_drag module): ~0.24 1/s horizontally for the Crazyflie
    omega = np.sqrt(CF.mass_kg * 9.81 / 4 / CF.propeller.k1_Ns2prad2)
    assert CF.drag_rate_ps[0] == pytest.approx(4 * omega * CF.rotor_drag.k_d_Ns2pradm / CF.mass_kg)
    assert CF.drag_rate_ps[2] == pytest.approx(4 * omega * CF.rotor_drag.k_z_Ns2pradm / CF.mass_kg)
    assert 0.2 < CF.drag_rate_ps[0] < 0.3
    assert CF.controller.kp_xy_Npm == 0.4 and CF.controller.kp_z_Npm == 1.25  # firmware defaults


def test_lead_settles_at_its_closed_form_on_a_constant_speed_segment():
    """Without integral action the lead at constant speed is c m v / k_p per axis (x: 2.9 cm at
    1.5 m/s for the Crazyflie, z with its own gain and drag)."""
    t, v, a, j = _cruise()
    lead = drag_lead(t, v, a, j, NO_KI, tail=False)
    closed = NO_KI.drag_rate_ps * NO_KI.mass_kg * v[-1] / NO_KI.controller.kp_Npm
    np.testing.assert_allclose(lead.value[-1], closed, rtol=1e-3, atol=1e-7)
    assert closed[0] == pytest.approx(0.0293, abs=5e-4)
    np.testing.assert_allclose(lead.rate[-1], 0.0, atol=1e-4)  # settled (its slowest mode decays as e^(-0.54 t))


def test_integral_action_moves_the_lead_onto_the_integrator_and_the_tail_unwinds_it():
    t, v, a, j = _cruise(total_s=6.0)
    lead = drag_lead(t, v, a, j, CF)
    plan_end = t.size - 1
    closed = CF.drag_rate_ps[0] * CF.mass_kg * v[-1, 0] / CF.controller.kp_xy_Npm
    assert 0.5 * closed < lead.value[plan_end, 0] < closed  # k_i has taken part of the drag over
    assert lead.t_s[-1] > t[-1] + 1.0  # a settle tail follows (the integrator unwinds)
    assert np.abs(lead.value[-1]).max() <= 0.0005 + 1e-9  # and ends within the residual
    assert lead.value[plan_end + 100 :, 0].min() < -0.002  # the wound-up integrator is met by a lag


def _smooth_cruise(speed_mps=(1.2, -0.6, 0.4), ramp_s=0.7, total_s=5.0, step_s=0.002):
    """Speed up along a smootherstep over ``ramp_s`` (jerk continuous), then cruise: (t, v, a, j)."""
    t = np.arange(0.0, total_s, step_s)
    s = np.clip(t / ramp_s, 0.0, 1.0)[:, None]
    vel = np.asarray(speed_mps)[None]
    v = (10 * s**3 - 15 * s**4 + 6 * s**5) * vel
    a = (30 * s**2 - 60 * s**3 + 30 * s**4) * vel / ramp_s
    j = (60 * s - 180 * s**2 + 120 * s**3) * vel / ramp_s**2
    return t, v, a, j


def test_prediction_of_the_compensated_reference_is_the_plan():
    """reference_error is the inverse of drag_lead: flying plan + lead, the vehicle lags it by the
    lead (in the linear model; here to 1 % of the lead (0.09 % measured), the rest is the finite-difference jerk of
    the lead the check feeds in)."""
    t, v, a, j = _smooth_cruise()
    lead = drag_lead(t, v, a, j, CF, tail=False)
    jerk_lead = np.gradient(lead.accel, t, axis=0)
    err = reference_error(t, v + lead.rate, a + lead.accel, j + jerk_lead, CF)
    assert np.abs(err.value - lead.value).max() < 1e-2 * np.abs(lead.value).max()
    # flying the plan itself, the vehicle lags by the drag (the lag the lead removes)
    t, v, a, j = _cruise(speed_mps=(1.2, -0.6, 0.4), accel_s=0.7, total_s=12.0)
    lag = reference_error(t, v, a, j, NO_KI)
    assert lag.value[-1, 0] == pytest.approx(
        NO_KI.drag_rate_ps[0] * NO_KI.mass_kg * v[-1, 0] / (NO_KI.controller.kp_xy_Npm), rel=2e-2
    )
