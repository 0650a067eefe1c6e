"""Controller authority usage of a hovering target rejecting a disturbance wrench (DESIGN.md s. 3).

The target must hold hover: its motors must together produce the collective thrust m g - F_z and the
body torques -tau (cancelling the disturbance). The mixer of (S0-14) maps motor thrusts
f = (f1..f4) to (T, tau_x, tau_y, tau_z):

    T     = f1 + f2 + f3 + f4
    tau_x = sum_i y_i f_i          = l/sqrt2 [(f3 + f4) - (f1 + f2)]   (S0-14a)
    tau_y = -sum_i x_i f_i         = l/sqrt2 [(f2 + f3) - (f1 + f4)]   (S0-14b)
    tau_z = k_t [(f2 + f4) - (f1 + f3)]                                 (S0-14c)

Authority usage = max over motors of the thrust change divided by the headroom in that direction
(up to f_max = T_max / n, down to f_min): 0 untouched, 1 a motor saturates, > 1 cannot be rejected.
Lateral disturbance forces (zero in the axial-flow model) are not counted: rejecting them needs tilt.
"""

from __future__ import annotations

import numpy as np

from proxplan.physics.vehicles import MOTOR_YAW_SIGNS, Vehicle


def mixer_matrix(vehicle: Vehicle) -> np.ndarray:
    """(4, 4) map from motor thrusts (N) to (T N, tau_x N m, tau_y N m, tau_z N m), (S0-14)."""
    pos = vehicle.rotor_positions_m
    return np.vstack(
        [
            np.ones(4),
            pos[:, 1],
            -pos[:, 0],
            vehicle.torque_to_thrust_m * MOTOR_YAW_SIGNS,
        ]
    )


def motor_thrust_changes_N(vehicle: Vehicle, force_N: np.ndarray, torque_Nm: np.ndarray) -> np.ndarray:
    """Per-motor thrust changes from hover (N, 4), N, that cancel force/torque (N, 3) (S0-14)."""
    force = np.atleast_2d(force_N)
    torque = np.atleast_2d(torque_Nm)
    demand = -np.column_stack([force[:, 2], torque[:, 0], torque[:, 1], torque[:, 2]])
    return np.linalg.solve(mixer_matrix(vehicle), demand.T).T


def motor_thrusts_N(vehicle: Vehicle, force_N: np.ndarray, torque_Nm: np.ndarray) -> np.ndarray:
    """Per-motor thrusts (N, 4), N, that hold hover (m g - F_z, -tau) against force/torque (N, 3)."""
    return vehicle.hover_thrust_per_rotor_N + motor_thrust_changes_N(vehicle, force_N, torque_Nm)


def authority_usage(vehicle: Vehicle, force_N: np.ndarray, torque_Nm: np.ndarray) -> np.ndarray:
    """Authority usage (N,) of ``vehicle`` rejecting force (N, 3) N and torque (N, 3) N m, -."""
    change = motor_thrust_changes_N(vehicle, force_N, torque_Nm)
    hover = vehicle.hover_thrust_per_rotor_N
    up_N = vehicle.max_thrust_per_rotor_N - hover
    down_N = hover - vehicle.min_motor_thrust_N
    if up_N <= 0.0 or down_N <= 0.0:
        raise ValueError(f"vehicle {vehicle.name!r} cannot hover within its motor thrust range")
    ratio = np.where(change > 0.0, change / up_N, -change / down_N)
    return ratio.max(axis=1)


def normalised_motor_map(vehicle: Vehicle) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(A (4, 3), up_N (4,), down_N (4,)) with per-motor thrust change delta_f = A @ (F_z, tau_x, tau_y).

    The target holds hover: the mixer (S0-14) must produce (m g - F_z, -tau_x, -tau_y, 0); the change
    from hover is M^-1 (-F_z, -tau_x, -tau_y, 0). ``up_N``/``down_N`` are the headrooms of
    DESIGN.md section 3 (to f_max and to f_min), N.
    """
    inv = np.linalg.inv(mixer_matrix(vehicle))
    a = -inv[:, :3]
    hover = vehicle.hover_thrust_per_rotor_N
    up = np.full(4, vehicle.max_thrust_per_rotor_N - hover)
    down = np.full(4, hover - vehicle.min_motor_thrust_N)
    return a, up, down


def cap_motor_thrusts(thrusts_N, max_N: float, min_N: float, fmax=np.maximum):
    """The Crazyflie firmware's ``powerDistributionCap`` (``power_distribution_quadrotor.c``, read,
    not copied) in newtons on the motor thrusts ``thrusts_N`` (a sequence of 4: floats, arrays or
    CasADi SX with ``fmax=casadi.fmax``): every motor is lowered by the excess of the highest one
    over ``max_N`` (attitude kept, thrust given up), then raised to ``min_N``."""
    highest = thrusts_N[0]
    for f in thrusts_N[1:]:
        highest = fmax(highest, f)
    excess = fmax(highest - max_N, 0.0)
    return [fmax(f - excess, min_N) for f in thrusts_N]
