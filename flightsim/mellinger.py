"""The Crazyflie firmware's Mellinger controller (Mellinger & Kumar, ICRA 2011; Lee et al. 2010),
in SI units, with the angular-velocity feed-forward of the reference evaluated from its jerk by
differential flatness, the firmware's rates and the firmware's motor-saturation rule.

Source read (not copied): bitcraze/crazyflie-firmware

* ``src/modules/src/controller/controller_mellinger.c``: the gains are a vehicle fact
  (``Vehicle.controller``, :mod:`proxplan.physics.controller_gains`: the firmware's defaults in SI
  for the crazyflie-2.1, scaled to the same closed-loop poles for other types, a vehicle file's
  ``controller:`` overrides them).
  Structure: F_des = m a_ref + Kp e_p + Kd e_v + Ki int(e_p) (+ m g e_z); thrust = F_des . z_B;
  z_B,des = F_des/|F_des|, x_B,des from yaw; e_R = 1/2 (R_des^T R - R^T R_des)^vee;
  M = -kR e_R + kw (w_ref - w) + ki_m int(-e_R) + kd_omega d/dt(w_ref - w) (the last on roll and
  pitch only, a difference of consecutive rate errors: with a moving w_ref it is the angular-
  acceleration feed-forward). The controller runs at ATTITUDE_RATE = 500 Hz
  (``stabilizer_types.h``), its dt = 1/500 s in the integrals and the difference.
* ``src/modules/src/crtp_commander_high_level.c``: set-points are evaluated at RATE_HL_COMMANDER
  = 100 Hz and held in between; ``pptraj.c`` ``poly4d_eval``: w_ref from the reference jerk,
  h_w = (j - (z_B . j) z_B) / |a + g e_z|, w_x = -h_w . y_B, w_y = h_w . x_B, w_z = z_B,z dyaw/dt
  (Mellinger & Kumar eq. 7) -- :func:`reference_body_rates`.
* ``src/modules/src/power_distribution_quadrotor.c``: the legacy mix (thrust +- roll/2 +- pitch/2
  +- yaw per motor) and ``powerDistributionCap``: when the highest motor command exceeds the
  maximum, every motor is lowered by the excess (attitude kept, thrust given up), then each is
  raised to the idle floor. :func:`proxplan.physics.cap_motor_thrusts` applies that rule in newtons.

The mixer is the (S0-14) one (``proxplan.physics.authority.mixer_matrix``), which is the legacy
mix in newtons. The controller's mass parameter is the vehicle's mass (the user sets
``ctrlMel.mass``); frames: world z up, body x forward; the firmware's pitch sign flips cancel in SI
form.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from proxplan.flightsim.dynamics import GRAVITY_ROTORPY_MPS2, cross, rotation
from proxplan.physics import (
    FIRMWARE_CONTROLLER_RATE_HZ,
    FIRMWARE_SETPOINT_RATE_HZ,
    Vehicle,
    cap_motor_thrusts,
    mixer_matrix,
)

CONTROLLER_RATE_HZ = FIRMWARE_CONTROLLER_RATE_HZ
"""ATTITUDE_RATE of the firmware (stabilizer_types.h): the controller period is 1/500 s
(:data:`proxplan.physics.FIRMWARE_CONTROLLER_RATE_HZ`)."""
SETPOINT_RATE_HZ = FIRMWARE_SETPOINT_RATE_HZ
"""RATE_HL_COMMANDER (stabilizer_types.h): the trajectory is evaluated at 100 Hz and held
(:data:`proxplan.physics.FIRMWARE_SETPOINT_RATE_HZ`)."""
CONTROLLER_STATE_SIZE = 10
"""Controller memory per vehicle: int e_p (3) m s, int(-e_R) (3) rad s, previous roll/pitch rate
errors (2) rad/s, a flag 'previous rate error valid' (1), spare (1)."""


@dataclass(frozen=True)
class MellingerGains:
    """Gains of the Mellinger law in SI units for one vehicle, and its mixer."""

    mass_kg: float
    kp_Npm: tuple[float, float, float]  # position P, N/m
    kd_Nspm: tuple[float, float, float]  # velocity D, N s/m
    ki_Npms: tuple[float, float, float]  # position I, N/(m s)
    i_range_ms: tuple[float, float, float]  # bound of int e_p, m s
    kR_Nmprad: tuple[float, float, float]  # attitude P, N m/rad
    kw_Nmsprad: tuple[float, float, float]  # rate D, N m s/rad
    ki_m_Nmpras: tuple[float, float, float]  # attitude I, N m/(rad s)
    i_range_m_rads: tuple[float, float, float]  # bound of int(-e_R), rad s
    kd_omega_Nms2prad: float  # roll/pitch rate-error derivative, N m s^2/rad
    mix_inv: tuple  # 4x4: (T N, tau_x, tau_y, tau_z N m) -> motor thrusts N, (S0-14)
    max_motor_thrust_N: float
    min_motor_thrust_N: float


def _mix_inv(vehicle: Vehicle) -> tuple:
    inv = np.linalg.inv(mixer_matrix(vehicle))
    return tuple(tuple(float(x) for x in row) for row in inv)


def controller_gains(vehicle: Vehicle) -> MellingerGains:
    """The law's numbers for ``vehicle``: its gains (``Vehicle.controller``, SI), its mass and mixer."""
    g = vehicle.controller
    return MellingerGains(
        mass_kg=vehicle.mass_kg,
        kp_Npm=(g.kp_xy_Npm, g.kp_xy_Npm, g.kp_z_Npm),
        kd_Nspm=(g.kd_xy_Nspm, g.kd_xy_Nspm, g.kd_z_Nspm),
        ki_Npms=(g.ki_xy_Npms, g.ki_xy_Npms, g.ki_z_Npms),
        i_range_ms=(g.i_range_xy_ms, g.i_range_xy_ms, g.i_range_z_ms),
        kR_Nmprad=(g.kR_xy_Nmprad, g.kR_xy_Nmprad, g.kR_z_Nmprad),
        kw_Nmsprad=(g.kw_xy_Nmsprad, g.kw_xy_Nmsprad, g.kw_z_Nmsprad),
        ki_m_Nmpras=(g.ki_m_xy_Nmprads, g.ki_m_xy_Nmprads, g.ki_m_z_Nmprads),
        i_range_m_rads=(g.i_range_m_xy_rads, g.i_range_m_xy_rads, g.i_range_m_z_rads),
        kd_omega_Nms2prad=g.kd_omega_rp_Nms2prad,
        mix_inv=_mix_inv(vehicle),
        max_motor_thrust_N=vehicle.max_thrust_per_rotor_N,
        min_motor_thrust_N=vehicle.min_motor_thrust_N,
    )


def reference_body_rates(acc_mps2: np.ndarray, jerk_mps3: np.ndarray) -> np.ndarray:
    """Body rates (K, 3), rad/s, of a vehicle following the reference with acceleration (K, 3),
    m/s^2, and jerk (K, 3), m/s^3, world frame, at yaw 0 (differential flatness, Mellinger & Kumar
    2011 eq. 7; firmware ``pptraj.c``): z_B = (a + g e_z)/|a + g e_z|, y_B = z_B x e_x normalised,
    x_B = y_B x z_B, h_w = (j - (z_B . j) z_B)/|a + g e_z|, w = (-h_w . y_B, h_w . x_B, 0)."""
    acc = np.atleast_2d(np.asarray(acc_mps2, dtype=float))
    jerk = np.atleast_2d(np.asarray(jerk_mps3, dtype=float))
    thrust = acc + np.array([0.0, 0.0, GRAVITY_ROTORPY_MPS2])
    mag = np.linalg.norm(thrust, axis=1, keepdims=True)
    zb = thrust / mag
    yb = np.cross(zb, np.array([1.0, 0.0, 0.0]))
    yb /= np.linalg.norm(yb, axis=1, keepdims=True)
    xb = np.cross(yb, zb)
    h = (jerk - np.sum(zb * jerk, axis=1, keepdims=True) * zb) / mag
    return np.column_stack([-np.sum(h * yb, axis=1), np.sum(h * xb, axis=1), np.zeros(len(acc))])


def _clamp(val, bound):
    return ca.fmin(ca.fmax(val, -bound), bound)


def mellinger_control(g: MellingerGains, s, ref, mem, dt_s: float, ff_force_N=None, ff_torque_body_Nm=None):
    """One controller period for state ``s`` (17, see proxplan.flightsim.dynamics), reference
    ``ref`` (12): position m, velocity m/s, acceleration m/s^2 (world frame) and body-rate
    feed-forward rad/s (body frame, :func:`reference_body_rates`), and controller memory ``mem``
    (:data:`CONTROLLER_STATE_SIZE`); ``dt_s`` the controller period, s. Compensates a predicted
    disturbance force (3, world, N) and torque (3, body, N m) when given.

    Returns (motor thrusts (4) N after the firmware's cap, commanded thrusts (4) N before it,
    collective thrust N, body moments (3) N m, new memory)."""
    x, v, q, w = s[0:3], s[3:6], s[6:10], s[10:13]
    rx, rv, ra, rw = ref[0:3], ref[3:6], ref[6:9], ref[9:12]
    e_p = [rx[k] - x[k] for k in range(3)]  # firmware sign: set-point minus state
    e_v = [rv[k] - v[k] for k in range(3)]
    i_p = [_clamp(mem[k] + e_p[k] * dt_s, g.i_range_ms[k]) for k in range(3)]
    f_des = [
        g.mass_kg * (ra[k] + (GRAVITY_ROTORPY_MPS2 if k == 2 else 0.0))
        + g.kp_Npm[k] * e_p[k]
        + g.kd_Nspm[k] * e_v[k]
        + g.ki_Npms[k] * i_p[k]
        for k in range(3)
    ]
    if ff_force_N is not None:
        f_des = [f_des[k] - ff_force_N[k] for k in range(3)]
    rot = rotation(q)
    zb = [rot[0][2], rot[1][2], rot[2][2]]
    thrust = f_des[0] * zb[0] + f_des[1] * zb[1] + f_des[2] * zb[2]
    n = ca.sqrt(f_des[0] ** 2 + f_des[1] ** 2 + f_des[2] ** 2)
    zd = [f_des[k] / n for k in range(3)]
    yd = cross(zd, [1.0, 0.0, 0.0])  # yaw 0: x_C = e_x
    ny = ca.sqrt(yd[0] ** 2 + yd[1] ** 2 + yd[2] ** 2)
    yd = [yd[k] / ny for k in range(3)]
    xd = cross(yd, zd)
    rd = [[xd[i], yd[i], zd[i]] for i in range(3)]  # columns x_B,des, y_B,des, z_B,des

    def rtr(a, b, i, j):  # (a^T b)_ij
        return a[0][i] * b[0][j] + a[1][i] * b[1][j] + a[2][i] * b[2][j]

    e_r = [
        0.5 * (rtr(rd, rot, 2, 1) - rtr(rot, rd, 2, 1)),
        0.5 * (rtr(rd, rot, 0, 2) - rtr(rot, rd, 0, 2)),
        0.5 * (rtr(rd, rot, 1, 0) - rtr(rot, rd, 1, 0)),
    ]
    e_w = [rw[k] - w[k] for k in range(3)]
    valid = mem[8]  # 0 on the first period: no derivative yet (the firmware's NaN check)
    d_ew = [valid * (e_w[k] - mem[6 + k]) / dt_s for k in range(2)] + [0.0]
    i_m = [_clamp(mem[3 + k] - e_r[k] * dt_s, g.i_range_m_rads[k]) for k in range(3)]
    moment = [
        -g.kR_Nmprad[k] * e_r[k]
        + g.kw_Nmsprad[k] * e_w[k]
        + g.ki_m_Nmpras[k] * i_m[k]
        + (g.kd_omega_Nms2prad * d_ew[k] if k < 2 else 0.0)
        for k in range(3)
    ]
    if ff_torque_body_Nm is not None:
        moment = [moment[k] - ff_torque_body_Nm[k] for k in range(3)]
    thrust = ca.fmax(thrust, 0.0)  # the firmware cuts the motors for a non-positive thrust command
    tm = [thrust, moment[0], moment[1], moment[2]]
    cmd = [sum(g.mix_inv[i][j] * tm[j] for j in range(4)) for i in range(4)]
    capped = cap_motor_thrusts(cmd, g.max_motor_thrust_N, g.min_motor_thrust_N, fmax=ca.fmax)
    new_mem = i_p + i_m + [e_w[0], e_w[1], 1.0, 0.0]
    return capped, cmd, thrust, moment, new_mem
