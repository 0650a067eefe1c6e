"""IMU disturbance measurement (S0-11, S0-13 + gyroscopic term) against a constructed truth."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from proxplan.identify.measure import MeasureOptions, measure_disturbance, motor_lag_compensated_N
from proxplan.physics import BUILTIN_VEHICLES, mixer_matrix

VEH = BUILTIN_VEHICLES["small-quad"]


def _flight(n: int = 600, dt: float = 0.01):
    """A vehicle rocking in roll/pitch and spinning in yaw, with a known disturbance wrench."""
    t = dt * np.arange(n)
    # rotation vector angles -> attitude; body rates from the exact derivative of R
    ang = np.column_stack([0.2 * np.sin(2.0 * t), 0.15 * np.sin(1.3 * t + 0.5), 1.5 * t])
    rot = Rotation.from_euler("xyz", ang)
    # body rates by a fine central difference of the attitude (exact to O(h^2))
    h = 1e-5
    r_p = Rotation.from_euler(
        "xyz", ang + h * np.column_stack([0.4 * np.cos(2.0 * t), 0.195 * np.cos(1.3 * t + 0.5), 1.5 + 0 * t])
    )
    omega = (rot.inv() * r_p).as_rotvec() / h
    omega_dot = np.gradient(omega, dt, axis=0, edge_order=2)
    J = np.asarray(VEH.inertia_diag_kgm2)
    f_true = np.column_stack([0.02 * np.sin(t), 0.01 + 0 * t, -0.1 - 0.05 * np.sin(0.7 * t)])
    tau_true = np.column_stack([0.002 * np.sin(1.1 * t), -0.001 + 0 * t, 0.0015 * np.cos(0.9 * t)])
    tau_p = J * omega_dot + np.cross(omega, J * omega) - rot.inv().apply(tau_true)  # body motor torque
    collective = VEH.weight_N * (1.0 + 0.1 * np.sin(0.5 * t))
    thrusts = np.linalg.solve(mixer_matrix(VEH), np.column_stack([collective, tau_p]).T).T
    z_b = rot.apply([0.0, 0.0, 1.0])
    accel = (collective[:, None] * z_b + f_true) / VEH.mass_kg
    return t, rot.as_quat(), accel, thrusts, omega, f_true, tau_true


@pytest.mark.parametrize("derivative", ["savgol", "triangular"])
def test_recovers_constructed_wrench(derivative: str) -> None:
    t, q, acc, thr, omega, f_true, tau_true = _flight()
    m = measure_disturbance(VEH, t, q, acc, thr, omega, options=MeasureOptions(derivative=derivative, window_s=0.09))
    inner = slice(20, -20)
    np.testing.assert_allclose(m.force_N[inner], f_true[inner], atol=2e-3)
    tol = 1e-4 if derivative == "savgol" else 3e-4
    np.testing.assert_allclose(m.torque_Nm[inner], tau_true[inner], atol=tol)


def test_gyroscopic_term_is_needed() -> None:
    """Dropping omega x J omega (as S0-13 does) would leave an error of its size."""
    t, q, acc, thr, omega, f_true, tau_true = _flight()
    J = np.asarray(VEH.inertia_diag_kgm2)
    gyro_mag = np.abs(np.cross(omega, J * omega)).max()
    m = measure_disturbance(VEH, t, q, acc, thr, omega)
    err = np.abs(m.torque_Nm[20:-20] - tau_true[20:-20]).max()
    assert gyro_mag > 5 * err  # the term is much larger than what remains


def test_motor_lag_first_order_step() -> None:
    cmd = np.zeros((300, 4))
    cmd[100:] = 1.0
    out = motor_lag_compensated_N(cmd, 0.01, 0.05)
    assert out[99, 0] == pytest.approx(0.0)
    assert out[100 + 5, 0] == pytest.approx(1 - np.exp(-1.0), rel=0.05)  # one time constant
    assert out[-1, 0] == pytest.approx(1.0, abs=1e-6)


def _rates(ang_of, t: np.ndarray, h: float = 1e-5) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Attitude (xyzw), body rates (rad/s) and their time derivative (rad/s^2) of the Euler angles ``ang_of(t)``
    (xyz, rad), by fine differences (exact to ~1e-8 of their size)."""

    def omega(tt: np.ndarray) -> np.ndarray:
        return (
            Rotation.from_euler("xyz", ang_of(tt)).inv() * Rotation.from_euler("xyz", ang_of(tt + h))
        ).as_rotvec() / h

    return Rotation.from_euler("xyz", ang_of(t)).as_quat(), omega(t), (omega(t + 1e-4) - omega(t - 1e-4)) / 2e-4


@pytest.mark.parametrize("derivative", ["savgol", "triangular"])
def test_a_vehicle_rocking_with_no_disturbance_measures_none(derivative: str) -> None:
    """The motors' torque turns the vehicle at 3 and 5 Hz (a controller at work) and no air acts on it: (S0-13)'s two
    sides are averaged by one filter, so what is measured is a few percent of J omega_dot at most (1.4 % with the
    Savitzky-Golay smoother, 0.9 % with the triangular one). With the Savitzky-Golay derivative of omega set against
    the smoothed motor torque (two kernels, until stop 81) it was 34 % (8.8 % triangular)."""
    t = 0.01 * np.arange(800)

    def ang_of(tt: np.ndarray) -> np.ndarray:
        return np.column_stack([0.05 * np.sin(2 * np.pi * 3.0 * tt), 0.04 * np.sin(2 * np.pi * 5.0 * tt + 0.5),
                                0.3 * tt])  # fmt: skip

    q, omega, omega_dot = _rates(ang_of, t)
    J = np.asarray(VEH.inertia_diag_kgm2)
    tau_p = J * omega_dot + np.cross(omega, J * omega)  # body: every bit of the rotation is the motors'
    thrusts = np.linalg.solve(mixer_matrix(VEH), np.column_stack([np.full(len(t), VEH.weight_N), tau_p]).T).T
    accel = VEH.weight_N * Rotation.from_quat(q).apply([0.0, 0.0, 1.0]) / VEH.mass_kg
    m = measure_disturbance(VEH, t, q, accel, thrusts, omega, options=MeasureOptions(derivative=derivative))
    inner = slice(20, -20)
    rms = lambda x: float(np.sqrt(np.mean(x[inner, :2] ** 2)))  # noqa: E731  roll and pitch
    assert rms(m.torque_Nm) < 0.03 * rms(J * omega_dot), (rms(m.torque_Nm), rms(J * omega_dot))
