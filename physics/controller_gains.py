"""The gains of the position / attitude controller a vehicle flies (a vehicle fact: ``Vehicle.controller``).

The law is the Crazyflie firmware's Mellinger controller (Mellinger & Kumar, ICRA 2011), read from
bitcraze/crazyflie-firmware ``src/modules/src/controller/controller_mellinger.c`` (not copied):

    F_des = m a_ref + K_p e_p + K_d e_v + K_i int(e_p) dt + m g e_z      (e = set-point - state)
    M     = -K_R e_R + K_w (w_ref - w) + K_I int(-e_R) dt + k_dw d/dt(w_ref - w)   (roll / pitch)

Firmware defaults: position kp_xy 0.4 N/m, kd_xy 0.2 N s/m, ki_xy 0.05 N/(m s) (|int e| <= 2 m s);
kp_z 1.25 N/m, kd_z 0.4 N s/m, ki_z 1.5 N/(m s) (|int e| <= 0.4 m s). These are SI already (the
firmware multiplies by massThrust only at the output). Attitude gains are in motor-PWM units:
kR_xy 70000, kw_xy 20000, ki_m_xy 0 (|int| <= 1 rad s), kR_z 60000, kw_z 12000, ki_m_z 500
(|int| <= 1500 rad s), kd_omega_rp 200; :func:`firmware_gains` converts them to N m through
massThrust = 132000 PWM/N and the airframe (a motor PWM unit is 1/(4 massThrust) N of that motor's
thrust; the legacy mix gives roll/2 per motor at the +-y arm offset l/sqrt2, so tau_x = M_x 2 d /
(4 massThrust); yaw: tau_z = M_z 4 k_t / (4 massThrust)).

Users retune the firmware (``ctrlMel.kp_xy`` and friends); a vehicle file's ``controller:``
section overrides any gain (:mod:`proxplan.physics.vehicle_yaml`). Every gain in SI, unit in the name.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

FIRMWARE_MASS_THRUST_PWM_PER_N = 132000.0
"""``massThrust`` of controller_mellinger.c: PWM of the collective thrust command per N."""
FIRMWARE_CONTROLLER_RATE_HZ = 500.0
"""ATTITUDE_RATE of the firmware (``stabilizer_types.h``): the controller runs every 1/500 s, Hz."""
FIRMWARE_SETPOINT_RATE_HZ = 100.0
"""RATE_HL_COMMANDER of the firmware (``stabilizer_types.h``): the high-level commander evaluates an
uploaded trajectory at 100 Hz and the controller holds each set-point until the next, Hz."""
FIRMWARE_ATTITUDE_PWM = {
    "kR_xy": 70000.0,  # PWM per rad
    "kw_xy": 20000.0,  # PWM per rad/s
    "ki_m_xy": 0.0,  # PWM per rad s
    "kR_z": 60000.0,
    "kw_z": 12000.0,
    "ki_m_z": 500.0,
    "kd_omega_rp": 200.0,  # PWM per rad/s^2 (difference of consecutive rate errors over dt)
}
"""Attitude gains of controller_mellinger.c in motor-PWM units."""


@dataclass(frozen=True)
class ControllerGains:
    """Gains of the Mellinger law in SI units (module docstring); ``xy`` = the two horizontal
    position axes and the roll / pitch attitude axes, ``z`` = vertical position and yaw."""

    kp_xy_Npm: float  # position P, N/m
    kd_xy_Nspm: float  # velocity D, N s/m
    ki_xy_Npms: float  # position I, N/(m s)
    i_range_xy_ms: float  # bound of int(e_p) dt, m s
    kp_z_Npm: float
    kd_z_Nspm: float
    ki_z_Npms: float
    i_range_z_ms: float
    kR_xy_Nmprad: float  # attitude P, N m/rad
    kw_xy_Nmsprad: float  # rate D, N m s/rad
    ki_m_xy_Nmprads: float  # attitude I, N m/(rad s)
    i_range_m_xy_rads: float  # bound of int(-e_R) dt, rad s
    kR_z_Nmprad: float
    kw_z_Nmsprad: float
    ki_m_z_Nmprads: float
    i_range_m_z_rads: float
    kd_omega_rp_Nms2prad: float  # roll / pitch rate-error derivative, N m s^2/rad

    @property
    def kp_Npm(self) -> np.ndarray:
        """Position P per world axis (x, y, z), N/m."""
        return np.array([self.kp_xy_Npm, self.kp_xy_Npm, self.kp_z_Npm])

    @property
    def kd_Nspm(self) -> np.ndarray:
        """Velocity D per world axis, N s/m."""
        return np.array([self.kd_xy_Nspm, self.kd_xy_Nspm, self.kd_z_Nspm])

    @property
    def ki_Npms(self) -> np.ndarray:
        """Position I per world axis, N/(m s)."""
        return np.array([self.ki_xy_Npms, self.ki_xy_Npms, self.ki_z_Npms])


POSITIVE_GAINS = frozenset(
    {"kp_xy_Npm", "kd_xy_Nspm", "kp_z_Npm", "kd_z_Nspm", "kR_xy_Nmprad", "kw_xy_Nmsprad", "kR_z_Nmprad", "kw_z_Nmsprad"}
)
"""Gains that must be > 0 for the loop to hold position and attitude; the others (integral gains,
integral ranges, the rate-error derivative) may be 0 (off) but not negative."""
GAIN_NAMES = tuple(f.name for f in dataclasses.fields(ControllerGains))


def firmware_gains(arm_length_m: float, torque_to_thrust_m: float) -> ControllerGains:
    """The firmware's default gains on an airframe with ``arm_length_m`` (centre to motor axis, m)
    and yaw torque per thrust ``torque_to_thrust_m`` (k_t of S0-14c, m), in SI (module docstring)."""
    pwm_N = 1.0 / (4.0 * FIRMWARE_MASS_THRUST_PWM_PER_N)  # N of one motor per PWM unit
    rp = 2.0 * (arm_length_m / math.sqrt(2.0)) * pwm_N  # N m per PWM of the roll / pitch command
    yw = 4.0 * torque_to_thrust_m * pwm_N  # N m per PWM of the yaw command
    att = FIRMWARE_ATTITUDE_PWM
    return ControllerGains(
        kp_xy_Npm=0.4,
        kd_xy_Nspm=0.2,
        ki_xy_Npms=0.05,
        i_range_xy_ms=2.0,
        kp_z_Npm=1.25,
        kd_z_Nspm=0.4,
        ki_z_Npms=1.5,
        i_range_z_ms=0.4,
        kR_xy_Nmprad=att["kR_xy"] * rp,
        kw_xy_Nmsprad=att["kw_xy"] * rp,
        ki_m_xy_Nmprads=att["ki_m_xy"] * rp,
        i_range_m_xy_rads=1.0,
        kR_z_Nmprad=att["kR_z"] * yw,
        kw_z_Nmsprad=att["kw_z"] * yw,
        ki_m_z_Nmprads=att["ki_m_z"] * yw,
        i_range_m_z_rads=1500.0,
        kd_omega_rp_Nms2prad=att["kd_omega_rp"] * rp,
    )


def scaled_gains(
    reference: ControllerGains,
    reference_mass_kg: float,
    reference_inertia_kgm2: tuple[float, float, float],
    mass_kg: float,
    inertia_kgm2: tuple[float, float, float],
) -> ControllerGains:
    """``reference`` scaled to another vehicle so that every loop keeps its closed-loop poles:
    position gains x m / m_ref (N/m per kg kept), roll / pitch gains x J_xx / J_ref,xx, yaw gains
    x J_zz / J_ref,zz; integral ranges unchanged."""
    scale = dict.fromkeys(("kp_xy_Npm", "kd_xy_Nspm", "ki_xy_Npms", "kp_z_Npm", "kd_z_Nspm", "ki_z_Npms"),
                          mass_kg / reference_mass_kg)  # fmt: skip
    scale |= dict.fromkeys(("kR_xy_Nmprad", "kw_xy_Nmsprad", "ki_m_xy_Nmprads", "kd_omega_rp_Nms2prad"),
                           inertia_kgm2[0] / reference_inertia_kgm2[0])  # fmt: skip
    scale |= dict.fromkeys(
        ("kR_z_Nmprad", "kw_z_Nmsprad", "ki_m_z_Nmprads"), inertia_kgm2[2] / reference_inertia_kgm2[2]
    )
    return dataclasses.replace(reference, **{name: getattr(reference, name) * f for name, f in scale.items()})
