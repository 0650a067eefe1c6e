"""RotorPy's geometric SE(3) tracking controller (``rotorpy.controllers.quadrotor_control.SE3Control``,
Lee et al. 2010), vectorised over V vehicles.

Same law and same gains as RotorPy's ``SE3Control.update`` (tests compare the two):
F_des = m (-K_p e_x - K_d e_v + a_ref + g e_z); thrust u1 = F_des . b3; attitude error from
R_des (b3_des along F_des, yaw 0); moment u2 = J (-k_R e_R - k_w e_w) + w x J w; motor thrusts from
the inverse mixer; motor speeds omega = sqrt(f / k_eta). Frames: world z up; quaternions [x, y, z, w].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from rotorpy.controllers.quadrotor_control import SE3Control

from flightsim.dynamics import GRAVITY_ROTORPY_MPS2, BatchState, rotation_matrices


@dataclass(frozen=True)
class ControlOutput:
    """Commands for V vehicles."""

    cmd_motor_speeds_radps: np.ndarray  # (V, 4), unclipped
    cmd_motor_thrusts_N: np.ndarray  # (V, 4)
    cmd_thrust_N: np.ndarray  # (V,) collective thrust
    cmd_moment_Nm: np.ndarray  # (V, 3) body frame


class BatchSE3Control:
    """SE3Control for V vehicles, gains read from RotorPy's own ``SE3Control`` objects."""

    def __init__(self, params: list[dict]):
        ctrls = [SE3Control(p) for p in params]
        self.mass_kg = np.array([c.mass for c in ctrls])
        self.inertia = np.array([c.inertia for c in ctrls])
        self.kp_pos = np.array([c.kp_pos for c in ctrls], dtype=float)
        self.kd_pos = np.array([c.kd_pos for c in ctrls], dtype=float)
        self.kp_att = np.array([c.kp_att for c in ctrls], dtype=float)
        self.kd_att = np.array([c.kd_att for c in ctrls], dtype=float)
        self.tm_to_f = np.array([c.TM_to_f for c in ctrls])
        self.k_eta = np.array([c.k_eta for c in ctrls])

    def update(
        self,
        state: BatchState,
        ref_position_m: np.ndarray,
        ref_velocity_mps: np.ndarray,
        ref_acceleration_mps2: np.ndarray,
    ) -> ControlOutput:
        """Commands for reference position, velocity, acceleration (V, 3), world frame; yaw 0."""
        rot = rotation_matrices(state.q)
        f_des = self.mass_kg[:, None] * (
            -self.kp_pos * (state.x - ref_position_m)
            - self.kd_pos * (state.v - ref_velocity_mps)
            + ref_acceleration_mps2
        )
        f_des[:, 2] += self.mass_kg * GRAVITY_ROTORPY_MPS2
        b3 = rot[:, :, 2]
        u1 = np.einsum("vi,vi->v", f_des, b3)
        b3_des = f_des / np.linalg.norm(f_des, axis=1, keepdims=True)
        c1 = np.array([1.0, 0.0, 0.0])
        b2_des = np.cross(b3_des, c1)
        b2_des /= np.linalg.norm(b2_des, axis=1, keepdims=True)
        b1_des = np.cross(b2_des, b3_des)
        r_des = np.stack([b1_des, b2_des, b3_des], axis=2)
        s_err = 0.5 * (
            np.einsum("vji,vjk->vik", r_des, rot) - np.einsum("vji,vjk->vik", rot, r_des)
        )
        att_err = np.stack([-s_err[:, 1, 2], s_err[:, 0, 2], -s_err[:, 0, 1]], axis=1)
        w = state.w
        iw = np.einsum("vij,vj->vi", self.inertia, w)
        u2 = np.einsum(
            "vij,vj->vi", self.inertia, -self.kp_att[:, None] * att_err - self.kd_att[:, None] * w
        ) + np.cross(w, iw)
        tm = np.concatenate([u1[:, None], u2], axis=1)
        thrusts = np.einsum("vij,vj->vi", self.tm_to_f, tm)
        speeds = thrusts / self.k_eta[:, None]
        speeds = np.sign(speeds) * np.sqrt(np.abs(speeds))
        return ControlOutput(speeds, thrusts, u1, u2)
