"""The four built-in vehicle types, every number with its unit and its source.

Sources
-------
[S0]  Seed 000: Table I (propeller diameter, arm length, mass, maximum thrust) and section IV-B
      (c_ax, z0, c_rad of each vehicle's downwash), IV-C (b_v of the large quad's 8-inch propeller).
[RP]  RotorPy 3.0 vehicle parameter files: ``crazyflie_params.py`` (mass 0.03 kg, inertia,
      k_eta = 2.3e-8 N s^2/rad^2, 2500 rad/s max) and ``hummingbird_params.py`` (AscTec Hummingbird,
      8-inch propellers: k_eta = 5.57e-6 N s^2/rad^2, k_m = 1.36e-7 N m s^2/rad^2, inertia).
[NS]  ../shared/data/neural-swarm/README.md: masses of the Neural-Swarm vehicles (32 g, 67 g),
      Crazyflie 2.1 geometry (92 mm motor-to-motor diagonal, 45-47 mm propellers).
[F15] Foerster 2015, "System identification of the Crazyflie 2.0": torque/thrust ratio 0.005964 m.
[ET]  Eschmann et al. 2024 (cited in RotorPy's crazyflie_params.py): Crazyflie motor time constant
      0.072 s.
[FW]  bitcraze/crazyflie-firmware ``controller_mellinger.c`` default gains (read, not copied;
      :mod:`proxplan.physics.controller_gains`): the crazyflie-2.1 flies them as they are; every
      other type flies them scaled to the same closed-loop poles (position gains x m / m_cf,
      attitude gains x J / J_cf). The crazyflie-parrot too: with the defaults unchanged its 3.8x
      inertia meets only 1.3x the torque per PWM unit and it tracks 2x worse, so its users retune.
      Rotor drag [RP]: RotorPy's Crazyflie k_d, k_z scaled per rotor (:mod:`proxplan.physics.rotor_drag`).
[A]   Assumption, stated here, to be corrected by calibration (``proxplan identify``).
[M]   Measured in closed-loop simulation (``proxplan track-limits --vehicle NAME``,
      :mod:`proxplan.flightsim.tracking`): each type flies alone, with the default controller (the
      Crazyflie firmware's Mellinger law with rate feed-forward, :mod:`proxplan.flightsim.mellinger`)
      flying the drag-compensated reference the export uploads (:mod:`proxplan.planfile.reference`),
      a course of rest-to-rest jerk-limited segments at a ladder of limits; the fastest level whose
      99 % error quantile (against the plan) + 5 mm stays within 2 cm (and within thrust-to-weight
      and tilt) gives the limits, and that quantile + 5 mm the type's tracking tube. Without the
      compensation RotorPy's rotor drag against the firmware's soft position gain left a cruise lag
      of ~1.9 cm per m/s and tubes of ~5 cm at 1.25-1.75 m/s (docs/flying.md).

Derived values
--------------
* Static C_T (rev/s form) from a known k1: C_T = 4 pi^2 k1 / (rho D^4).
* Inertia of the S0 vehicles (not given by S0): scaled from the Crazyflie [RP] by m l^2
  (Jxx = 0.225 m l^2, Jzz = 0.455 m l^2); the same scaling reproduces the Hummingbird's inertia [RP]
  within 10 %, so it is a fair estimate for the large quad.
* b_v of propellers without a measurement: blade-element momentum theory, :mod:`proxplan.physics.propeller`.
"""

from __future__ import annotations

import math

from proxplan.physics.controller_gains import ControllerGains, firmware_gains, scaled_gains
from proxplan.physics.propeller import AIR_DENSITY_KGPM3, PropellerSpec
from proxplan.physics.rotor_drag import RotorDrag, rotorpy_rotor_drag
from proxplan.physics.vehicles import (
    GRAVITY_MPS2,
    TRACKING_COURSE,
    TUBE_BUDGET_M,
    TUBE_MARGIN_M,
    DownwashSpec,
    FrameSpec,
    KinematicLimits,
    TrackingMeasurement,
    Vehicle,
)

MEASURED_ON = "2026-11-26"


def _measured(name: str, limits: tuple[float, float, float], q_m: float, max_m: float, sat_s: float, limited_by: str):
    """Kinematic limits and tracking measurement of built-in type ``name`` [M]."""
    return KinematicLimits(*limits), TrackingMeasurement(
        controller="mellinger",
        tube_m=round(q_m + TUBE_MARGIN_M, 4),
        error_quantile=0.99,
        quantile_error_m=q_m,
        max_error_m=max_m,
        margin_m=TUBE_MARGIN_M,
        budget_m=TUBE_BUDGET_M,
        saturation_s=sat_s,
        limited_by=limited_by,
        course=TRACKING_COURSE,
        command=f"proxplan track-limits --vehicle {name} --budget {TUBE_BUDGET_M:g}",
        date=MEASURED_ON,
    )


_SMALL_QUAD_KIN, _SMALL_QUAD_TRACK = _measured(
    "small-quad",
    (2.0, 4.0, 16.0),
    0.01279,
    0.01282,
    0.088,
    "next faster level (1.25 m/s, 4 m/s^2, 40 m/s^3): error quantile 2.2 cm + margin 0.5 cm > budget 2.0 cm",
)

_LARGE_QUAD_KIN, _LARGE_QUAD_TRACK = _measured(
    "large-quad",
    (2.0, 2.5, 10.0),
    0.00894,
    0.00908,
    0.108,
    "next faster level (1 m/s, 3 m/s^2, 30 m/s^3): error quantile 1.9 cm + margin 0.5 cm > budget 2.0 cm",
)

_CRAZYFLIE_21_KIN, _CRAZYFLIE_21_TRACK = _measured(
    "crazyflie-2.1",
    (2.0, 4.0, 16.0),
    0.01423,
    0.01434,
    0.084,
    "next faster level (1.25 m/s, 4 m/s^2, 40 m/s^3): error quantile 3.4 cm + margin 0.5 cm > budget 2.0 cm",
)

_CRAZYFLIE_PARROT_KIN, _CRAZYFLIE_PARROT_TRACK = _measured(
    "crazyflie-parrot",
    (2.0, 4.0, 16.0),
    0.01441,
    0.01455,
    0.1,
    "next faster level (1.25 m/s, 4 m/s^2, 40 m/s^3): error quantile 3.7 cm + margin 0.5 cm > budget 2.0 cm",
)

_JXX_PER_ML2 = 1.43e-5 / (0.030 * 0.046**2)  # Crazyflie [RP] inertia over m l^2, -
_JZZ_PER_ML2 = 2.89e-5 / (0.030 * 0.046**2)


def _static_ct_from_k1(k1_Ns2prad2: float, diameter_m: float) -> float:
    """C_T (rev/s form) of a propeller whose k1 of f = k1 omega^2 is known, -."""
    return 4.0 * math.pi**2 * k1_Ns2prad2 / (AIR_DENSITY_KGPM3 * diameter_m**4)


def _scaled_inertia(mass_kg: float, arm_length_m: float) -> tuple[float, float, float]:
    jxx = _JXX_PER_ML2 * mass_kg * arm_length_m**2
    return (jxx, jxx, _JZZ_PER_ML2 * mass_kg * arm_length_m**2)


def _rotor_drag(mass_kg: float, propeller: PropellerSpec) -> RotorDrag:
    """RotorPy's Crazyflie rotor drag scaled to this rotor at this vehicle's hover [RP]."""
    k1 = propeller.k1_Ns2prad2
    return rotorpy_rotor_drag(k1, math.sqrt(mass_kg * GRAVITY_MPS2 / 4.0 / k1))


_CF_MASS_KG = 0.032  # [NS] 32 g with markers
_CF_ARM_M = 0.046  # [NS] 92 mm motor-to-motor diagonal / 2
_CF_INERTIA_KGM2 = (1.43e-5, 1.43e-5, 2.89e-5)  # [RP]
_CF_KT_M = 0.005964  # [F15]
_CF_GAINS = firmware_gains(_CF_ARM_M, _CF_KT_M)  # [FW] controller_mellinger.c defaults on the Crazyflie 2.1


def _scaled_gains(mass_kg: float, inertia_kgm2: tuple[float, float, float]) -> ControllerGains:
    """The Crazyflie 2.1's firmware gains scaled to the same closed-loop poles [FW]."""
    return scaled_gains(_CF_GAINS, _CF_MASS_KG, _CF_INERTIA_KGM2, mass_kg, inertia_kgm2)


_SMALL_PROPELLER = PropellerSpec(
    diameter_m=0.0508,  # [S0] Table I
    chord_m=0.0065,  # [A] 2-inch, 2-blade propeller, chord at 75 % R
    pitch_m=0.030,  # [A] 1.2-inch pitch
    n_blades=2,  # [A]
    thrust_coefficient=0.10,  # [A] static C_T of small hobby propellers, 0.08-0.12
)
_LARGE_PROPELLER = PropellerSpec(
    diameter_m=0.2032,  # [S0] Table I
    chord_m=0.016,  # [A] 8x4.5 propeller; gives solidity 0.10, near S1 Table 1 (0.095)
    pitch_m=0.1143,  # [A] 4.5-inch pitch of a common 8x4.5 propeller
    n_blades=2,
    thrust_coefficient=_static_ct_from_k1(5.57e-6, 0.2032),  # [RP] Hummingbird 8-inch k_eta
    b_v_measured=3.710e-7,  # [S0] IV-C, thrust stand, N m^-1 rad^-2 s^3
)
_CF_PROPELLER = PropellerSpec(
    diameter_m=0.046,  # [NS] 45-47 mm
    chord_m=0.0055,  # [A] measured-by-eye Crazyflie blade chord at 75 % R
    pitch_m=0.021,  # [A]
    n_blades=2,
    thrust_coefficient=_static_ct_from_k1(2.3e-8, 0.046),  # [RP] k_eta
)
_PARROT_PROPELLER = PropellerSpec(
    diameter_m=0.066,  # [A] about 2.6-inch propellers
    chord_m=0.008,  # [A]
    pitch_m=0.030,  # [A]
    n_blades=2,
    thrust_coefficient=0.12,  # [A]
)

SMALL_QUAD = Vehicle(
    name="small-quad",
    description="S0 Table I small quadcopter (2-inch propellers)",
    mass_kg=0.145,  # [S0] Table I
    arm_length_m=0.0585,  # [S0] Table I
    max_thrust_N=4.6,  # [S0] Table I
    inertia_diag_kgm2=_scaled_inertia(0.145, 0.0585),  # derived, see module docstring
    torque_to_thrust_m=0.006,  # [A] close to the Crazyflie's [F15] for a propeller of similar size
    propeller=_SMALL_PROPELLER,
    frame=FrameSpec(hub_side_m=0.045, arm_width_m=0.008, motor_pod_diameter_m=0.014),  # [A]
    downwash=DownwashSpec(c_ax=4.672, z0_m=0.033, c_rad=60.808),  # [S0] IV-B
    rotor_drag=_rotor_drag(0.145, _SMALL_PROPELLER),  # [RP] scaled
    controller=_scaled_gains(0.145, _scaled_inertia(0.145, 0.0585)),  # [FW] scaled
    kinematics=_SMALL_QUAD_KIN,  # [M] proxplan track-limits
    tracking=_SMALL_QUAD_TRACK,  # [M] the measurement behind the limits and the tube
    motor_time_constant_s=0.04,  # [A] 5-10 inch brushless value (DEFAULT_MOTOR_TIME_CONSTANT_S), s
    sources={
        "mass/arm/propeller/max thrust": "S0 Table I",
        "c_ax/z0/c_rad": "S0 section IV-B",
        "inertia": "Crazyflie (RotorPy) scaled by m l^2",
        "frame, blade geometry, C_T, k_t": "assumed; calibrate with proxplan identify",
        "b_v": "blade-element theory (S1-4..S1-8)",
    },
)

LARGE_QUAD = Vehicle(
    name="large-quad",
    description="S0 Table I large quadcopter (8-inch propellers)",
    mass_kg=0.650,  # [S0] Table I
    arm_length_m=0.165,  # [S0] Table I
    max_thrust_N=27.0,  # [S0] Table I
    inertia_diag_kgm2=_scaled_inertia(0.650, 0.165),  # derived, see module docstring
    torque_to_thrust_m=1.36e-7 / 5.57e-6,  # [RP] Hummingbird k_m / k_eta (8-inch), m
    propeller=_LARGE_PROPELLER,
    frame=FrameSpec(hub_side_m=0.10, arm_width_m=0.018, motor_pod_diameter_m=0.030),  # [A]
    downwash=DownwashSpec(c_ax=4.886, z0_m=0.110, c_rad=24.936),  # [S0] IV-B
    rotor_drag=_rotor_drag(0.650, _LARGE_PROPELLER),  # [RP] scaled
    controller=_scaled_gains(0.650, _scaled_inertia(0.650, 0.165)),  # [FW] scaled
    kinematics=_LARGE_QUAD_KIN,  # [M] proxplan track-limits
    tracking=_LARGE_QUAD_TRACK,  # [M] the measurement behind the limits and the tube
    motor_time_constant_s=0.04,  # [A] 5-10 inch brushless value (DEFAULT_MOTOR_TIME_CONSTANT_S), s
    sources={
        "mass/arm/propeller/max thrust": "S0 Table I",
        "c_ax/z0/c_rad": "S0 section IV-B",
        "b_v": "S0 section IV-C (measured)",
        "k1, k_t": "RotorPy hummingbird_params (8-inch propellers)",
        "inertia": "Crazyflie (RotorPy) scaled by m l^2; matches Hummingbird within 10 %",
        "frame, blade geometry": "assumed; calibrate with proxplan identify",
    },
)

CRAZYFLIE_21 = Vehicle(
    name="crazyflie-2.1",
    description="Bitcraze Crazyflie 2.1 with mocap markers (Neural-Swarm cf50-52)",
    mass_kg=_CF_MASS_KG,  # [NS] 32 g with markers
    arm_length_m=_CF_ARM_M,  # [NS] 92 mm motor-to-motor diagonal / 2
    max_thrust_N=4 * 2.3e-8 * 2500.0**2,  # [RP] k_eta omega_max^2 per motor, 0.575 N total
    inertia_diag_kgm2=_CF_INERTIA_KGM2,  # [RP]
    torque_to_thrust_m=_CF_KT_M,  # [F15]
    propeller=_CF_PROPELLER,
    frame=FrameSpec(hub_side_m=0.030, arm_width_m=0.005, motor_pod_diameter_m=0.009),  # [A]
    downwash=DownwashSpec(c_ax=4.672, z0_m=0.28 * 0.092, c_rad=60.808),  # [A] S0 small quad, z0/L kept
    rotor_drag=_rotor_drag(_CF_MASS_KG, _CF_PROPELLER),  # [RP] (its 30 g values at 32 g)
    controller=_CF_GAINS,  # [FW] the firmware's defaults
    kinematics=_CRAZYFLIE_21_KIN,  # [M] proxplan track-limits
    tracking=_CRAZYFLIE_21_TRACK,  # [M] the measurement behind the limits and the tube
    motor_time_constant_s=0.072,  # [ET], s
    sources={
        "mass, geometry": "Neural-Swarm README",
        "inertia, k1, max thrust": "RotorPy crazyflie_params",
        "k_t": "Foerster 2015",
        "c_ax/c_rad": "assumed equal to S0 small quad; z0 scaled by L",
    },
)

CRAZYFLIE_PARROT = Vehicle(
    name="crazyflie-parrot",
    description="Crazyflie 2.1 electronics on a Parrot frame with larger propellers (Neural-Swarm cf101-102)",
    mass_kg=0.067,  # [NS] 67 g
    arm_length_m=0.060,  # [A] geometry undocumented [NS]; Parrot Mambo-class frame
    max_thrust_N=1.40,  # [A] thrust-to-weight about 2.1
    inertia_diag_kgm2=_scaled_inertia(0.067, 0.060),  # derived as for the S0 vehicles
    torque_to_thrust_m=0.0075,  # [A]
    propeller=_PARROT_PROPELLER,
    frame=FrameSpec(hub_side_m=0.035, arm_width_m=0.007, motor_pod_diameter_m=0.012),  # [A]
    downwash=DownwashSpec(c_ax=4.672, z0_m=0.28 * 0.120, c_rad=60.808),  # [A] as crazyflie-2.1
    rotor_drag=_rotor_drag(0.067, _PARROT_PROPELLER),  # [RP] scaled
    controller=_scaled_gains(0.067, _scaled_inertia(0.067, 0.060)),  # [FW] scaled: its users retune ctrlMel
    kinematics=_CRAZYFLIE_PARROT_KIN,  # [M] proxplan track-limits
    tracking=_CRAZYFLIE_PARROT_TRACK,  # [M] the measurement behind the limits and the tube
    motor_time_constant_s=0.072,  # [ET] same motors and firmware as the Crazyflie, s
    sources={
        "mass": "Neural-Swarm README",
        "geometry, propellers, thrust": "assumed (undocumented); calibrate with proxplan identify",
    },
)

BUILTIN_VEHICLES: dict[str, Vehicle] = {v.name: v for v in (SMALL_QUAD, LARGE_QUAD, CRAZYFLIE_21, CRAZYFLIE_PARROT)}
