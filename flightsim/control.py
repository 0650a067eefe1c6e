"""RotorPy's geometric SE(3) tracking controller (``rotorpy.controllers.quadrotor_control.SE3Control``,
Lee et al. 2010), written with scalar arithmetic (floats or CasADi SX) for :mod:`proxplan.flightsim.stepper`.

Same law and same gains as RotorPy's ``SE3Control.update`` (tests compare the two):
F_des = m (-K_p e_x - K_d e_v + a_ref + g e_z); thrust u1 = F_des . b3; R_des with b3_des along
F_des and yaw 0; moment u2 = J (-k_R e_R - k_w w) + w x J w; motor thrusts from RotorPy's inverse
mixer TM_to_f; motor speeds omega = sign(f) sqrt(|f| / k_eta). Frames: world z up, [x, y, z, w].

Feed-forward (``proxplan simulate --feedforward``, not part of RotorPy's law): a predicted external
force F_ff (world frame, N) and torque tau_ff (body frame, N m) are compensated,
F_des -> F_des - F_ff and u2 -> u2 - tau_ff. With zero feed-forward the law is RotorPy's exactly.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np
from rotorpy.controllers.quadrotor_control import SE3Control

from proxplan.flightsim.dynamics import GRAVITY_ROTORPY_MPS2, cross, matvec, rotation


@dataclass(frozen=True)
class ControllerConstants:
    """Gains and allocation of RotorPy's SE3Control for one vehicle."""

    mass_kg: float
    inertia: tuple  # 3x3, kg m^2
    kp_pos: tuple  # (3,) 1/s^2
    kd_pos: tuple  # (3,) 1/s
    kp_att: float  # 1/s^2
    kd_att: float  # 1/s
    tm_to_f: tuple  # 4x4 inverse mixer: (T, tau_x, tau_y, tau_z) -> rotor thrusts
    k_eta: float  # N/(rad/s)^2

    @classmethod
    def from_params(cls, p: dict) -> ControllerConstants:
        ctrl = SE3Control(p)
        tup = lambda a: tuple(tuple(float(v) for v in row) for row in np.asarray(a))  # noqa: E731
        return cls(
            mass_kg=float(ctrl.mass),
            inertia=tup(ctrl.inertia),
            kp_pos=tuple(float(k) for k in ctrl.kp_pos),
            kd_pos=tuple(float(k) for k in ctrl.kd_pos),
            kp_att=float(ctrl.kp_att),
            kd_att=float(ctrl.kd_att),
            tm_to_f=tup(ctrl.TM_to_f),
            k_eta=float(ctrl.k_eta),
        )


def _normalize(a):
    n = ca.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])
    return [a[0] / n, a[1] / n, a[2] / n]


def se3_control(c: ControllerConstants, s, ref_x, ref_v, ref_a, ff_force_N=None, ff_torque_body_Nm=None):
    """Commands for state ``s`` (17, see proxplan.flightsim.dynamics) and reference position, velocity,
    acceleration (3 each), world frame, compensating the predicted disturbance force (3, world
    frame, N) and torque (3, body frame, N m) when given. Returns (motor speeds (4) rad/s
    unclipped, motor thrusts (4) N, collective thrust u1 N, body moments u2 (3) N m)."""
    x, v, q, w = s[0:3], s[3:6], s[6:10], s[10:13]
    rot = rotation(q)
    f_des = [
        c.mass_kg
        * (
            -c.kp_pos[k] * (x[k] - ref_x[k])
            - c.kd_pos[k] * (v[k] - ref_v[k])
            + ref_a[k]
            + (GRAVITY_ROTORPY_MPS2 if k == 2 else 0.0)
        )
        for k in range(3)
    ]
    if ff_force_N is not None:
        f_des = [f_des[k] - ff_force_N[k] for k in range(3)]
    b3 = [rot[0][2], rot[1][2], rot[2][2]]
    u1 = f_des[0] * b3[0] + f_des[1] * b3[1] + f_des[2] * b3[2]
    b3_des = _normalize(f_des)
    b2_des = _normalize(cross(b3_des, [1.0, 0.0, 0.0]))
    b1_des = cross(b2_des, b3_des)
    r_des = [[b1_des[i], b2_des[i], b3_des[i]] for i in range(3)]  # columns b1, b2, b3

    def rtr(a, b, i, j):  # (a^T b)_ij
        return a[0][i] * b[0][j] + a[1][i] * b[1][j] + a[2][i] * b[2][j]

    s12 = 0.5 * (rtr(r_des, rot, 1, 2) - rtr(rot, r_des, 1, 2))
    s02 = 0.5 * (rtr(r_des, rot, 0, 2) - rtr(rot, r_des, 0, 2))
    s01 = 0.5 * (rtr(r_des, rot, 0, 1) - rtr(rot, r_des, 0, 1))
    att_err = [-s12, s02, -s01]
    iw = matvec(c.inertia, w)
    u2_core = matvec(c.inertia, [-c.kp_att * att_err[k] - c.kd_att * w[k] for k in range(3)])
    wxiw = cross(w, iw)
    u2 = [u2_core[k] + wxiw[k] for k in range(3)]
    if ff_torque_body_Nm is not None:
        u2 = [u2[k] - ff_torque_body_Nm[k] for k in range(3)]
    tm = [u1, u2[0], u2[1], u2[2]]
    thrusts = [sum(c.tm_to_f[i][j] * tm[j] for j in range(4)) for i in range(4)]
    speeds = [ca.sign(f) * ca.sqrt(ca.fabs(f) / c.k_eta) for f in thrusts]
    return speeds, thrusts, u1, u2
