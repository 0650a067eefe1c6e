"""Thrust coefficient from flight data (seed 001): per-sample C_T, LS fit of eq 25, RLS eqs 27-30.

Per sample (S1-16, S1-19): the measured thrust is T_exp = m alpha_zB (specific force along body z,
N), and per rotor C_T,exp = (T_exp / n) / (rho A (omega R)^2), with omega from the logged motor
thrusts through f_i = k1 omega_i^2 (S0-5), R the rotor radius (m), A = pi R^2 (m^2).

Regressors of (S1-25), body frame (x forward, z up), u, v, w body velocities (m/s):
    mu = sqrt(u^2 + v^2) / (omega R)                      advance ratio (S1-1), -
    lambda = (v_i - w) / (omega R)                        inflow ratio (S1-2): climbing (w > 0)
                                                          raises the flow through the disk, -
    C_T = C_T0 + C_Tlambda lambda + C_Tmu mu + C_Tv v + C_Tw w + C_Tmu2 mu^2      (S1-25)
with v_i = sqrt(T_hover / (2 rho A)) the hover induced velocity (m/s). Written y = x^T theta (S1-27).

:func:`fit_ls` solves (S1-27) in the least-squares sense (with the parameter covariance);
:func:`rls` runs (S1-28..S1-30) with a forgetting factor lambda_f in (0, 1] (1 = the paper's form):
    K_k = P_{k-1} x_k / (lambda_f + x_k^T P_{k-1} x_k)
    theta_k = theta_{k-1} + K_k (y_k - x_k^T theta_{k-1})
    P_k = (P_{k-1} - K_k x_k^T P_{k-1}) / lambda_f
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from proxplan.physics import AIR_DENSITY_KGPM3, Vehicle

REGRESSOR_NAMES = ("C_T0", "C_Tlambda", "C_Tmu", "C_Tv_spm", "C_Tw_spm", "C_Tmu2")
"""Parameter names of (S1-25) in regressor order (units: -, -, -, s/m, s/m, -)."""


@dataclass(frozen=True)
class ThrustSamples:
    """Per-sample thrust coefficient and the (S1-25) regressors, N samples."""

    c_t: np.ndarray  # (N,) measured C_T,exp per rotor, -
    regressors: np.ndarray  # (N, 6) [1, lambda, mu, v, w, mu^2] (S1-27)


@dataclass(frozen=True)
class LSFit:
    theta: np.ndarray  # (6,) parameters, REGRESSOR_NAMES order
    std: np.ndarray  # (6,) one-sigma uncertainty
    r2: float  # coefficient of determination, -


def thrust_samples(
    vehicle: Vehicle,
    quat_xyzw: np.ndarray,
    accel_mps2: np.ndarray,
    velocity_mps: np.ndarray,
    motor_thrust_N: np.ndarray,
    *,
    air_density_kgpm3: float = AIR_DENSITY_KGPM3,
) -> ThrustSamples:
    """C_T,exp and regressors from N samples (world-frame accel (N,3) m/s^2 and velocity (N,3) m/s,
    attitude (N,4) body->world xyzw, motor thrusts (N,4) N)."""
    rot = Rotation.from_quat(quat_xyzw)
    acc_b = rot.inv().apply(accel_mps2)
    vel_b = rot.inv().apply(velocity_mps)
    prop = vehicle.propeller
    omega = np.sqrt(np.clip(motor_thrust_N, 1e-9, None) / prop.k1_Ns2prad2).mean(axis=1)  # rad/s
    tip_mps = omega * prop.radius_m
    t_exp = vehicle.mass_kg * acc_b[:, 2]  # (S1-16)
    c_t = (t_exp / vehicle.n_rotors) / (air_density_kgpm3 * prop.disk_area_m2 * tip_mps**2)  # (S1-19)
    v_i = np.sqrt(vehicle.hover_thrust_per_rotor_N / (2.0 * air_density_kgpm3 * prop.disk_area_m2))
    mu = np.hypot(vel_b[:, 0], vel_b[:, 1]) / tip_mps
    lam = (v_i - vel_b[:, 2]) / tip_mps
    x = np.column_stack([np.ones_like(mu), lam, mu, vel_b[:, 1], vel_b[:, 2], mu**2])
    return ThrustSamples(c_t=c_t, regressors=x)


def fit_ls(x: np.ndarray, y: np.ndarray) -> LSFit:
    """Least squares of y (N,) = x (N, p) theta (S1-27), with the covariance s^2 (X^T X)^-1."""
    theta, *_ = np.linalg.lstsq(x, y, rcond=None)
    res = y - x @ theta
    dof = max(len(y) - x.shape[1], 1)
    cov = (res @ res / dof) * np.linalg.pinv(x.T @ x)
    ss = float(((y - y.mean()) ** 2).sum())
    r2 = 1.0 - float(res @ res) / ss if ss > 0 else 0.0
    return LSFit(theta=theta, std=np.sqrt(np.clip(np.diag(cov), 0.0, None)), r2=r2)


def rls(
    x: np.ndarray,
    y: np.ndarray,
    *,
    forgetting: float = 0.995,
    theta0: np.ndarray | None = None,
    p0: float = 1e3,
) -> np.ndarray:
    """Recursive least squares (S1-28..S1-30) with forgetting factor; parameter history (N, p).

    ``theta0`` defaults to zeros (the paper starts from the LS solution: pass ``fit_ls(...).theta``).
    """
    if not 0.0 < forgetting <= 1.0:
        raise ValueError(f"forgetting factor must be in (0, 1], got {forgetting}")
    n, p = x.shape
    theta = np.zeros(p) if theta0 is None else np.array(theta0, dtype=float)
    P = np.eye(p) * p0
    out = np.empty((n, p))
    for k in range(n):
        xk = x[k]
        px = P @ xk
        gain = px / (forgetting + xk @ px)  # (S1-29)
        theta = theta + gain * (y[k] - xk @ theta)  # (S1-28)
        P = (P - np.outer(gain, px)) / forgetting  # (S1-30)
        out[k] = theta
    return out
