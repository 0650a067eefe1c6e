"""Our :class:`proxplan.physics.vehicles.Vehicle` -> RotorPy ``quad_params`` dict.

Motor numbering: RotorPy takes rotor positions as an ordered dict ``r1..r4`` and a yaw-direction
sign per rotor, with no fixed convention of its own. We pass our rotors in (S0-14) order
(motor 1 (+x, -y), 2 (-x, -y), 3 (-x, +y), 4 (+x, +y)), so RotorPy rotor index i IS our motor i,
and ``rotor_directions = MOTOR_YAW_SIGNS`` = (-1, +1, -1, +1) reproduces
tau_z = k_t [(f2 + f4) - (f1 + f3)] (S0-14c) through RotorPy's M_yaw = dir k_m omega^2.

Values our vehicle definition does not hold are set here, each documented:

* ``k_eta`` = k1 (S0-5), N s^2 rad^-2; ``k_m`` = k_t k1, N m s^2 rad^-2 (yaw torque per omega^2);
* rotor speed limits from the per-motor thrust range: omega = sqrt(f / k1), rad/s;
* motor time constant ``tau_m``: ``Vehicle.motor_time_constant_s`` (sourced in proxplan.physics.builtin_vehicles);
* rotor drag ``k_d`` and induced inflow ``k_z`` (N per (rad/s m/s)): ``Vehicle.rotor_drag``
  (:mod:`proxplan.physics.rotor_drag`); translational lift and flapping are 0 (RotorPy's Crazyflie default);
* parasitic frame drag c_D = 0 (RotorPy's Crazyflie default: our downwash drag covers the frame).
"""

from __future__ import annotations

import math

import numpy as np

from proxplan.physics import MOTOR_YAW_SIGNS, Vehicle

ATTITUDE_KP = 310.0  # attitude P gain, 1/s^2 (rotorpy crazyflie kp_att)
ATTITUDE_KD = 57.0  # attitude D gain, 1/s (rotorpy crazyflie kd_att)


def quad_params(vehicle: Vehicle) -> dict:
    """RotorPy ``quad_params`` dict for ``vehicle`` (keys and units as rotorpy/vehicles/*_params.py)."""
    k1 = vehicle.propeller.k1_Ns2prad2
    pos = vehicle.rotor_positions_m
    jxx, jyy, jzz = vehicle.inertia_diag_kgm2
    return {
        "mass": vehicle.mass_kg,
        "Ixx": jxx,
        "Iyy": jyy,
        "Izz": jzz,
        "Ixy": 0.0,
        "Iyz": 0.0,
        "Ixz": 0.0,
        "num_rotors": 4,
        "rotor_pos": {f"r{i + 1}": pos[i].copy() for i in range(4)},
        "rotor_directions": MOTOR_YAW_SIGNS.copy(),
        "rI": np.zeros(3),
        "c_Dx": 0.0,
        "c_Dy": 0.0,
        "c_Dz": 0.0,
        "k_eta": k1,
        "k_m": vehicle.torque_to_thrust_m * k1,
        "k_d": vehicle.rotor_drag.k_d_Ns2pradm,
        "k_z": vehicle.rotor_drag.k_z_Ns2pradm,
        "k_h": 0.0,
        "k_flap": 0.0,
        "tau_m": vehicle.motor_time_constant_s,
        "rotor_speed_min": math.sqrt(max(vehicle.min_motor_thrust_N, 0.0) / k1),
        "rotor_speed_max": math.sqrt(vehicle.max_thrust_per_rotor_N / k1),
        "motor_noise_std": 0.0,
        "k_w": 1.0,
        "k_v": 10.0,
        "kp_att": ATTITUDE_KP,
        "kd_att": ATTITUDE_KD,
    }
