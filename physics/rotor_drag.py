"""Rotor drag (a vehicle fact: ``Vehicle.rotor_drag``), in RotorPy's form.

RotorPy (``rotorpy.vehicles.multirotor``, ``compute_body_wrench``) gives each rotor i spinning at
omega_i (rad/s) moving through the air at v_i (m/s, body frame, including w x r_i) the force

    f_i = -omega_i (k_d v_i,x, k_d v_i,y, k_z v_i,z)          (body frame, N)

with the in-plane drag coefficient ``k_d`` and the axial (induced-inflow) coefficient ``k_z``, both
in N per (rad/s x m/s) = N s^2 rad^-1 m^-1. Near hover (omega_i = omega_hover, small tilt) the four
rotors give a force -n omega_hover (k_d v_x, k_d v_y, k_z v_z): a drag acceleration of
``c v`` per axis with c = n omega_hover k / m, 1/s (:func:`drag_rate_ps`) -- about 0.24 1/s
horizontally for a Crazyflie, which its position gain (kp_xy 0.4 N/m on 32 g) turns into a lag of
~1.9 cm per m/s unless the reference leads the plan (:mod:`proxplan.physics.closed_loop`).

Values: RotorPy's Crazyflie (``crazyflie_params.py``: k_eta 2.3e-8 N s^2/rad^2 at 30 g, k_d
10.2506e-7, k_z 7.553e-7), scaled to another vehicle so that the drag per m/s relative to the hover
thrust per rotor is the Crazyflie's: k ~ k1 omega_hover (:func:`rotorpy_rotor_drag`). A calibrated
value can replace them in a vehicle file or a model file (``rotor_drag:``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

CRAZYFLIE_K_ETA_NS2PRAD2 = 2.3e-08  # thrust per omega^2, N s^2/rad^2, rotorpy crazyflie_params
CRAZYFLIE_HOVER_OMEGA_RADPS = math.sqrt(0.03 * 9.81 / 4 / CRAZYFLIE_K_ETA_NS2PRAD2)  # RotorPy's CF at 30 g, rad/s
CRAZYFLIE_K_D_NS2PRADM = 10.2506e-07  # in-plane rotor drag, N s^2/(rad m), rotorpy crazyflie_params
CRAZYFLIE_K_Z_NS2PRADM = 7.553e-07  # axial (induced inflow), N s^2/(rad m), rotorpy crazyflie_params


@dataclass(frozen=True)
class RotorDrag:
    """Per-rotor drag coefficients (module docstring): in-plane ``k_d_Ns2pradm`` and axial
    ``k_z_Ns2pradm``, N per (rad/s x m/s); both >= 0."""

    k_d_Ns2pradm: float
    k_z_Ns2pradm: float


def rotorpy_rotor_drag(k1_Ns2prad2: float, hover_omega_radps: float) -> RotorDrag:
    """RotorPy's Crazyflie coefficients scaled to a rotor with thrust coefficient ``k1_Ns2prad2``
    (f = k1 omega^2, N s^2/rad^2) hovering at ``hover_omega_radps`` (rad/s): k x (k1 omega_hover) /
    (k1_cf omega_hover,cf), i.e. the same drag per m/s relative to the hover thrust per rotor."""
    scale = (k1_Ns2prad2 * hover_omega_radps) / (CRAZYFLIE_K_ETA_NS2PRAD2 * CRAZYFLIE_HOVER_OMEGA_RADPS)
    return RotorDrag(CRAZYFLIE_K_D_NS2PRADM * scale, CRAZYFLIE_K_Z_NS2PRADM * scale)


def drag_rate_ps(drag: RotorDrag, n_rotors: int, hover_omega_radps: float, mass_kg: float) -> np.ndarray:
    """Linearised rotor-drag acceleration per m/s near hover, per world axis (x, y, z), 1/s:
    c = n omega_hover (k_d, k_d, k_z) / m (module docstring)."""
    per = n_rotors * hover_omega_radps / mass_kg
    return np.array([drag.k_d_Ns2pradm, drag.k_d_Ns2pradm, drag.k_z_Ns2pradm]) * per
