"""RotorPy's multirotor dynamics with an external wrench, vectorised over vehicles.

RotorPy (``rotorpy.vehicles.multirotor.Multirotor``) has no hook for external forces. Two forms are
offered, both the SAME model (rigid body, first-order motor lag, rotor drag / induced inflow, yaw
moments; RotorPy's ``_s_dot_fn`` and ``compute_body_wrench``):

* :class:`ExternalWrenchMultirotor` subclasses RotorPy's ``Multirotor`` and adds an external force
  (world frame, N) and torque (body frame, N m) to its state derivative; one vehicle, RotorPy's own
  ``step`` (scipy ``solve_ivp``, about 1 ms per step). Used as the reference in tests.
* :class:`BatchDynamics` evaluates the same derivative for V vehicles at once with numpy and
  integrates it with classic fixed-step RK4 (control and external wrench held over the step, as in
  RotorPy's ``step``). Tests check its derivative against RotorPy's ``_s_dot_fn``.

State arrays (V vehicles): position ``x`` (V, 3) m, velocity ``v`` (V, 3) m/s, both world frame
(z up); attitude ``q`` (V, 4) body-to-world quaternion [x, y, z, w] (RotorPy order); body rates
``w`` (V, 3) rad/s, body frame; ``rotor_speeds`` (V, 4) rad/s in (S0-14) motor order.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from rotorpy.vehicles.multirotor import Multirotor

GRAVITY_ROTORPY_MPS2 = 9.81  # RotorPy's g, m/s^2


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


@dataclass
class BatchState:
    """Mutable state of V vehicles (shapes in the module docstring)."""

    x: np.ndarray
    v: np.ndarray
    q: np.ndarray
    w: np.ndarray
    rotor_speeds: np.ndarray

    def copy(self) -> "BatchState":
        return BatchState(*(a.copy() for a in (self.x, self.v, self.q, self.w, self.rotor_speeds)))


def rotation_matrices(q: np.ndarray) -> np.ndarray:
    """Body-to-world rotation matrices (V, 3, 3) from unit quaternions (V, 4) [x, y, z, w]."""
    x, y, z, w = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    r = np.empty((q.shape[0], 3, 3))
    r[:, 0, 0] = 1 - 2 * (y * y + z * z)
    r[:, 0, 1] = 2 * (x * y - z * w)
    r[:, 0, 2] = 2 * (x * z + y * w)
    r[:, 1, 0] = 2 * (x * y + z * w)
    r[:, 1, 1] = 1 - 2 * (x * x + z * z)
    r[:, 1, 2] = 2 * (y * z - x * w)
    r[:, 2, 0] = 2 * (x * z - y * w)
    r[:, 2, 1] = 2 * (y * z + x * w)
    r[:, 2, 2] = 1 - 2 * (x * x + y * y)
    return r


class BatchDynamics:
    """RotorPy's ``Multirotor`` dynamics for V vehicles, from their ``quad_params`` dicts."""

    def __init__(self, params: list[dict], *, wind_mps: np.ndarray | None = None):
        for p in params:
            if p.get("k_flap", 0.0) != 0.0:
                raise ValueError("BatchDynamics does not model rotor flapping (k_flap must be 0)")
        self.n = len(params)
        self.mass_kg = np.array([p["mass"] for p in params])
        self.inertia = np.array(
            [
                [[p["Ixx"], p["Ixy"], p["Ixz"]], [p["Ixy"], p["Iyy"], p["Iyz"]], [p["Ixz"], p["Iyz"], p["Izz"]]]
                for p in params
            ]
        )
        self.inv_inertia = np.linalg.inv(self.inertia)
        self.rotor_pos_m = np.array([np.array(list(p["rotor_pos"].values())) for p in params])  # (V,4,3)
        self.rotor_dir = np.array([p["rotor_directions"] for p in params], dtype=float)  # (V, 4)
        self.k_eta = np.array([p["k_eta"] for p in params])
        self.k_m = np.array([p["k_m"] for p in params])
        self.k_d = np.array([p.get("k_d", 0.0) for p in params])
        self.k_z = np.array([p.get("k_z", 0.0) for p in params])
        self.k_h = np.array([p.get("k_h", 0.0) for p in params])
        self.c_d = np.array([[p.get("c_Dx", 0.0), p.get("c_Dy", 0.0), p.get("c_Dz", 0.0)] for p in params])
        self.tau_m_s = np.array([p["tau_m"] for p in params])
        self.speed_min = np.array([p["rotor_speed_min"] for p in params])
        self.speed_max = np.array([p["rotor_speed_max"] for p in params])
        self.wind_mps = np.zeros(3) if wind_mps is None else np.asarray(wind_mps, dtype=float)
        self.gravity_mps2 = GRAVITY_ROTORPY_MPS2

    def clip_speeds(self, cmd_rotor_speeds: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Clip commands (V, 4) rad/s to the motor range; also return the (V, 4) saturation mask."""
        lo = self.speed_min[:, None]
        hi = self.speed_max[:, None]
        clipped = np.clip(cmd_rotor_speeds, lo, hi)
        return clipped, clipped != cmd_rotor_speeds

    def derivative(
        self,
        state: BatchState,
        cmd_rotor_speeds: np.ndarray,
        ext_force_N: np.ndarray,
        ext_torque_body_Nm: np.ndarray,
    ) -> tuple[np.ndarray, ...]:
        """(x_dot, v_dot, q_dot, w_dot, rotor_accel) of RotorPy's ``_s_dot_fn`` plus the external
        force (V, 3) N, world frame, and torque (V, 3) N m, body frame."""
        q, w, omega = state.q, state.w, state.rotor_speeds
        rot = rotation_matrices(q)
        rotor_accel = (cmd_rotor_speeds - omega) / self.tau_m_s[:, None]
        qx, qy, qz, qw = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
        wx, wy, wz = w[:, 0], w[:, 1], w[:, 2]
        q_dot = 0.5 * np.stack(
            [
                qw * wx - qz * wy + qy * wz,
                qz * wx + qw * wy - qx * wz,
                -qy * wx + qx * wy + qw * wz,
                -qx * wx - qy * wy - qz * wz,
            ],
            axis=1,
        )
        airspeed_b = np.einsum("vji,vj->vi", rot, state.v - self.wind_mps)  # R^T (v - wind)
        # local airspeed at each rotor hub: v_b + w x r_i, shape (V, 4, 3)
        local = airspeed_b[:, None, :] + np.cross(w[:, None, :], self.rotor_pos_m)
        omega_sq = omega * omega
        thrust = self.k_eta[:, None] * omega_sq + self.k_h[:, None] * (local[..., 0] ** 2 + local[..., 1] ** 2)
        # rotor drag (H force) at each hub, RotorPy: H = -omega * diag(k_d, k_d, k_z) local
        rotor_force = -omega[..., None] * local * np.stack([self.k_d, self.k_d, self.k_z], axis=1)[:, None, :]
        rotor_force[..., 2] += thrust
        speed = np.linalg.norm(airspeed_b, axis=1)
        drag = -speed[:, None] * self.c_d * airspeed_b
        force_b = rotor_force.sum(axis=1) + drag
        moment_b = np.cross(self.rotor_pos_m, rotor_force).sum(axis=1)
        moment_b[:, 2] += (self.rotor_dir * self.k_m[:, None] * omega_sq).sum(axis=1)
        force_w = np.einsum("vij,vj->vi", rot, force_b)
        v_dot = (force_w + ext_force_N) / self.mass_kg[:, None]
        v_dot[:, 2] -= self.gravity_mps2
        iw = np.einsum("vij,vj->vi", self.inertia, w)
        w_dot = np.einsum("vij,vj->vi", self.inv_inertia, moment_b + ext_torque_body_Nm - np.cross(w, iw))
        return state.v, v_dot, q_dot, w_dot, rotor_accel

    def rk4_step(
        self,
        state: BatchState,
        cmd_rotor_speeds: np.ndarray,
        ext_force_N: np.ndarray,
        ext_torque_body_Nm: np.ndarray,
        dt_s: float,
    ) -> BatchState:
        """One classic RK4 step of length ``dt_s`` (s) with commands (already clipped) and external
        wrench held constant; the quaternion is renormalised afterwards (as RotorPy does)."""
        args = (cmd_rotor_speeds, ext_force_N, ext_torque_body_Nm)
        fields = ("x", "v", "q", "w", "rotor_speeds")
        k1 = self.derivative(state, *args)
        s2 = BatchState(*(getattr(state, f) + 0.5 * dt_s * d for f, d in zip(fields, k1)))
        k2 = self.derivative(s2, *args)
        s3 = BatchState(*(getattr(state, f) + 0.5 * dt_s * d for f, d in zip(fields, k2)))
        k3 = self.derivative(s3, *args)
        s4 = BatchState(*(getattr(state, f) + dt_s * d for f, d in zip(fields, k3)))
        k4 = self.derivative(s4, *args)
        new = BatchState(
            *(
                getattr(state, f) + (dt_s / 6.0) * (a + 2.0 * b + 2.0 * c + d)
                for f, a, b, c, d in zip(fields, k1, k2, k3, k4)
            )
        )
        new.q /= np.linalg.norm(new.q, axis=1, keepdims=True)
        return new
