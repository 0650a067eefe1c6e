"""RotorPy's multirotor dynamics with an external wrench.

RotorPy (``rotorpy.vehicles.multirotor.Multirotor``) has no hook for external forces. Two forms are
offered, both the SAME model (rigid body, first-order motor lag, rotor drag / induced inflow,
translational lift, parasitic drag, yaw moments: RotorPy's ``_s_dot_fn`` and
``compute_body_wrench``; rotor flapping is not supported, ``k_flap`` must be 0):

* :class:`ExternalWrenchMultirotor` subclasses RotorPy's ``Multirotor`` and adds an external force
  (world frame, N) and torque (body frame, N m) to its state derivative; one vehicle, RotorPy's own
  ``step`` (scipy ``solve_ivp``, about 1 ms per step). The reference in tests.
* :func:`state_derivative` writes the same derivative with scalar arithmetic that works both on
  floats and on CasADi SX symbols, so :mod:`proxplan.flightsim.stepper` compiles it (with the controller
  and an RK4 step) into one fast function for all vehicles. Tests check it against RotorPy.

State vector of one vehicle, 17 entries: position x (3) m and velocity v (3) m/s, world frame, z up;
attitude q (4) body-to-world quaternion [x, y, z, w] (RotorPy order); body rates w (3) rad/s, body
frame; rotor speeds (4) rad/s in (S0-14) motor order (RotorPy's wind state is a constant here).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np
from rotorpy.vehicles.multirotor import Multirotor

GRAVITY_ROTORPY_MPS2 = 9.81  # RotorPy's g, m/s^2
STATE_SIZE = 17


class ExternalWrenchMultirotor(Multirotor):
    """RotorPy ``Multirotor`` plus an external force ``ext_force_N`` (3,) in the WORLD frame and an
    external torque ``ext_torque_Nm`` (3,) in the BODY frame, held constant over each ``step``."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.ext_force_N = np.zeros(3)
        self.ext_torque_Nm = np.zeros(3)

    def _s_dot_fn(self, t, s, cmd_rotor_speeds):
        s_dot = super()._s_dot_fn(t, s, cmd_rotor_speeds)
        s_dot[3:6] += self.ext_force_N / self.mass
        s_dot[10:13] += self.inv_inertia @ self.ext_torque_Nm
        return s_dot


@dataclass(frozen=True)
class VehicleConstants:
    """Numbers of one RotorPy ``quad_params`` dict used by the dynamics (units as RotorPy's)."""

    mass_kg: float
    inertia: tuple  # 3x3 nested tuples, kg m^2
    inv_inertia: tuple  # 3x3
    rotor_pos_m: tuple  # 4 x (x, y, z), body frame
    rotor_dir: tuple  # 4 yaw signs
    k_eta: float  # N/(rad/s)^2
    k_m: float  # N m/(rad/s)^2
    k_d: float  # N/(rad/s m/s)
    k_z: float  # N/(rad/s m/s)
    k_h: float  # N/(m/s)^2
    c_d: tuple  # (c_Dx, c_Dy, c_Dz), N/(m/s)^2
    tau_m_s: float
    speed_min_radps: float
    speed_max_radps: float

    @classmethod
    def from_params(cls, p: dict) -> VehicleConstants:
        if p.get("k_flap", 0.0) != 0.0:
            raise ValueError("rotor flapping (k_flap != 0) is not modelled by proxplan.flightsim.dynamics")
        inertia = np.array(
            [[p["Ixx"], p["Ixy"], p["Ixz"]], [p["Ixy"], p["Iyy"], p["Iyz"]], [p["Ixz"], p["Iyz"], p["Izz"]]]
        )
        tup = lambda a: tuple(tuple(float(v) for v in row) for row in a)  # noqa: E731
        return cls(
            mass_kg=float(p["mass"]),
            inertia=tup(inertia),
            inv_inertia=tup(np.linalg.inv(inertia)),
            rotor_pos_m=tup(np.array(list(p["rotor_pos"].values()))),
            rotor_dir=tuple(float(d) for d in p["rotor_directions"]),
            k_eta=float(p["k_eta"]),
            k_m=float(p["k_m"]),
            k_d=float(p.get("k_d", 0.0)),
            k_z=float(p.get("k_z", 0.0)),
            k_h=float(p.get("k_h", 0.0)),
            c_d=(float(p.get("c_Dx", 0.0)), float(p.get("c_Dy", 0.0)), float(p.get("c_Dz", 0.0))),
            tau_m_s=float(p["tau_m"]),
            speed_min_radps=float(p["rotor_speed_min"]),
            speed_max_radps=float(p["rotor_speed_max"]),
        )


# ---------------------------------------------------------------- scalar helpers (float or SX)


def cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def matvec(m, v):
    return [m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2] for i in range(3)]


def mat_t_vec(m, v):
    """m^T v."""
    return [m[0][i] * v[0] + m[1][i] * v[1] + m[2][i] * v[2] for i in range(3)]


def rotation(q):
    """Body-to-world rotation matrix (3 x 3 nested lists) of quaternion [x, y, z, w]."""
    x, y, z, w = q
    return [
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ]


def state_derivative(
    c: VehicleConstants, s, cmd_rotor_speeds, ext_force_world_N, ext_torque_body_Nm, wind_mps=(0.0, 0.0, 0.0)
):
    """d/dt of the 17-entry state ``s`` (RotorPy's ``_s_dot_fn``) with rotor speed commands (4)
    rad/s (already clipped), external force (3) N, world frame, and torque (3) N m, body frame."""
    v, q, w, om = s[3:6], s[6:10], s[10:13], s[13:17]  # position s[0:3] does not enter
    rot = rotation(q)
    rotor_accel = [(cmd_rotor_speeds[i] - om[i]) / c.tau_m_s for i in range(4)]
    qx, qy, qz, qw = q
    wx, wy, wz = w
    q_dot = [
        0.5 * (qw * wx - qz * wy + qy * wz),
        0.5 * (qz * wx + qw * wy - qx * wz),
        0.5 * (-qy * wx + qx * wy + qw * wz),
        0.5 * (-qx * wx - qy * wy - qz * wz),
    ]
    air_b = mat_t_vec(rot, [v[k] - wind_mps[k] for k in range(3)])
    force_b = [0.0, 0.0, 0.0]
    moment_b = [0.0, 0.0, 0.0]
    for i in range(4):
        r = c.rotor_pos_m[i]
        wr = cross(w, r)
        local = [air_b[k] + wr[k] for k in range(3)]
        om2 = om[i] * om[i]
        thrust = c.k_eta * om2 + c.k_h * (local[0] * local[0] + local[1] * local[1])
        f_i = [-om[i] * c.k_d * local[0], -om[i] * c.k_d * local[1], thrust - om[i] * c.k_z * local[2]]
        m_i = cross(list(r), f_i)
        for k in range(3):
            force_b[k] = force_b[k] + f_i[k]
            moment_b[k] = moment_b[k] + m_i[k]
        moment_b[2] = moment_b[2] + c.rotor_dir[i] * c.k_m * om2
    if any(c.c_d):
        speed = ca.sqrt(air_b[0] ** 2 + air_b[1] ** 2 + air_b[2] ** 2)
        for k in range(3):
            force_b[k] = force_b[k] - speed * c.c_d[k] * air_b[k]
    force_w = matvec(rot, force_b)
    v_dot = [(force_w[k] + ext_force_world_N[k]) / c.mass_kg for k in range(3)]
    v_dot[2] = v_dot[2] - GRAVITY_ROTORPY_MPS2
    iw = matvec(c.inertia, w)
    wxiw = cross(w, iw)
    w_dot = matvec(c.inv_inertia, [moment_b[k] + ext_torque_body_Nm[k] - wxiw[k] for k in range(3)])
    return list(v) + v_dot + q_dot + w_dot + rotor_accel
