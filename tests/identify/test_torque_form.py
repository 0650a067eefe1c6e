"""(S0-13) balanced through one kernel: with no disturbance, a vehicle rolling and pitching at 3-7 Hz reads
(nearly) no torque in the ``impulse`` form, where the ``smoothed`` form leaves J (S'(omega) - S(omega_dot))
behind (issue 35, round 35Z); and a prediction is seen as the measurement sees it."""

from __future__ import annotations

import numpy as np

from proxplan.identify.measure import MeasureOptions, measure_disturbance, smoothed_on_clock
from proxplan.physics import BUILTIN_VEHICLES, mixer_matrix

CF = BUILTIN_VEHICLES["crazyflie-2.1"]


def _rates(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Body rates (N, 3) rad/s and their derivative (N, 3) rad/s^2."""
    f = np.array([[3.0, 7.0], [4.0, 6.5], [1.0, 2.0]])  # Hz per axis, two tones
    a = np.array([[0.6, 0.4], [0.5, 0.3], [0.1, 0.05]])  # rad/s
    w = sum(a[:, k] * np.sin(2 * np.pi * f[:, k] * t[:, None] + k) for k in range(2))
    wd = sum(a[:, k] * 2 * np.pi * f[:, k] * np.cos(2 * np.pi * f[:, k] * t[:, None] + k) for k in range(2))
    return w, wd


def _measured_torque(form: str) -> np.ndarray:
    t = 0.01 * np.arange(1000)
    w, wd = _rates(t)
    J = np.asarray(CF.inertia_diag_kgm2)
    tau = J * wd + np.cross(w, J * w)  # the motors' torque that turns the body so: no disturbance (S0-13)
    wrench = np.column_stack([np.full(len(t), CF.weight_N), tau])
    thrust = np.linalg.solve(mixer_matrix(CF), wrench.T).T  # (N, 4) per motor (S0-14)
    quat = np.tile([0.0, 0.0, 0.0, 1.0], (len(t), 1))
    accel = np.column_stack([0 * t, 0 * t, thrust.sum(axis=1) / CF.mass_kg])
    opts = MeasureOptions(torque_form=form)
    return measure_disturbance(CF, t, quat, accel, thrust, w, options=opts).torque_Nm[20:-20]


def test_impulse_form_reads_no_torque_where_none_acts() -> None:
    smoothed = np.sqrt(np.mean(_measured_torque("smoothed") ** 2))
    impulse = np.sqrt(np.mean(_measured_torque("impulse") ** 2))
    assert impulse < 0.05 * smoothed, (impulse, smoothed)  # measured 6.3e-7 against 6.2e-5 N m


def test_a_predicted_torque_is_seen_through_the_same_kernel() -> None:
    """A disturbance torque tau_a (no motion) is measured as S'(integral tau_a): what smoothed_on_clock gives a
    prediction's torque columns in the impulse form."""
    t = 0.01 * np.arange(600)
    tau_a = np.column_stack([1e-3 * np.sin(2 * np.pi * 5 * t), 5e-4 * np.sign(np.sin(2 * np.pi * 1.3 * t)), 0 * t])
    opts = MeasureOptions(torque_form="impulse")
    thrust = np.tile(CF.weight_N / 4, (len(t), 4))
    quat = np.tile([0.0, 0.0, 0.0, 1.0], (len(t), 1))
    accel = np.column_stack([0 * t, 0 * t, np.full(len(t), 9.80665)])
    # the body does not turn, so the motors' torque balances tau_a: tau_p = -tau_a
    thrust = np.linalg.solve(mixer_matrix(CF), np.column_stack([np.full(len(t), CF.weight_N), -tau_a]).T).T
    measured = measure_disturbance(CF, t, quat, accel, thrust, np.zeros((len(t), 3)), options=opts).torque_Nm
    seen = smoothed_on_clock(t, np.column_stack([0 * t, tau_a]), options=opts, torque_from=1)[:, 1:]
    np.testing.assert_allclose(measured, seen, atol=1e-9)
    assert np.abs(measured - tau_a).max() > 1e-4  # the kernel does act (the square wave is rounded)
