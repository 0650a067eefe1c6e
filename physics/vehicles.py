"""Typed vehicle definitions: mass properties, propellers, frame geometry, downwash parameters.

Frames: body frame x forward, y left, z up, origin at the centre of mass. Vehicles are quadrotors in
X configuration with the motor numbering of (S0-14), which is also the Crazyflie's:
motor 1 at (+x, -y), 2 at (-x, -y), 3 at (-x, +y), 4 at (+x, +y).

Every field carries its SI unit in its name. Parameters the seed papers do not give are documented
in :mod:`proxplan.physics.builtin_vehicles` with their source or derivation.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from proxplan.physics.controller_gains import ControllerGains
from proxplan.physics.propeller import PropellerSpec, derived_b_v
from proxplan.physics.rotor_drag import RotorDrag, drag_rate_ps

GRAVITY_MPS2 = 9.81
"""Standard gravity used throughout, m/s^2."""


MOTOR_DIRECTIONS_XY = np.array([[1.0, -1.0], [-1.0, -1.0], [-1.0, 1.0], [1.0, 1.0]])
"""Unit-diagonal signs (x, y) of motors 1..4 in the body frame, (S0-14) numbering, shape (4, 2)."""

MOTOR_YAW_SIGNS = np.array([-1.0, 1.0, -1.0, 1.0])
"""Yaw-torque sign per motor: tau_z = k_t [(f2 + f4) - (f1 + f3)] (S0-14c), shape (4,)."""


@dataclass(frozen=True)
class KinematicLimits:
    """Norm limits a vehicle and its controller track: speed m/s, acceleration m/s^2, jerk m/s^3."""

    max_speed_mps: float
    max_accel_mps2: float
    max_jerk_mps3: float


DEFAULT_TRACKING_TUBE_M = 0.06
"""Tracking tube of a vehicle without a tracking measurement, m: the single figure every plan used
before the per-type measurement (RotorPy's SE(3) law at 1 m/s, 1 m/s^2, 2 m/s^3, docs/flying.md)."""


TUBE_MARGIN_M = 0.005
"""Margin added to a measured error quantile to make a tracking tube, m: covers the calibration
course not exercising every combination of moves a plan makes, position noise (0.5 mm mocap) and
timing jitter (``proxplan track-limits --margin``)."""
TUBE_BUDGET_M = 0.02
"""Largest tube the built-in measurement accepts, m (``proxplan track-limits --budget``): with the
rotor drag compensated (the export's reference, :mod:`proxplan.planfile.reference`) every built-in
type keeps at least 2 m/s within it (docs/flying.md)."""
TRACKING_COURSE = "rest-to-rest course: 2.1 m horizontal, 0.6 m vertical, 1.6 m diagonal, 0.2 m hops (COURSE_M)"
"""Name of the calibration course of :mod:`proxplan.flightsim.tracking` (``COURSE_M``)."""


@dataclass(frozen=True)
class TrackingMeasurement:
    """How a vehicle's kinematic limits and tracking tube were measured in closed-loop simulation
    (``proxplan track-limits``, :mod:`proxplan.flightsim.tracking`).

    The vehicle flew a course of rest-to-rest jerk-limited segments at increasing limits with
    ``controller``; at the limits kept, the ``error_quantile`` quantile of its position error over
    the flight was ``quantile_error_m`` (largest ``max_error_m``), m; the tube is that quantile plus
    ``margin_m``: ``tube_m``, m, kept within ``budget_m``, m. ``limited_by`` says what stopped the
    next faster level; ``saturation_s`` is the motor-saturated time at the kept level, s.
    """

    controller: str
    tube_m: float
    error_quantile: float
    quantile_error_m: float
    max_error_m: float
    margin_m: float
    budget_m: float
    saturation_s: float
    limited_by: str
    course: str
    command: str
    date: str


DEFAULT_MOTOR_TIME_CONSTANT_S = 0.04
"""First-order motor speed time constant of vehicles that do not state one, s ([A] a typical value
for 5-10 inch brushless propulsion)."""


@dataclass(frozen=True)
class FrameSpec:
    """Frame geometry projected on the body x-y plane, for the drag integral (S0-3, S0-4).

    The frame is a square hub, four straight arms from the hub to the motors, and a round motor pod
    under each propeller; all lie in the body x-y plane at the centre of mass height.
    """

    hub_side_m: float  # side of the square central hub, m
    arm_width_m: float  # width of each arm, m
    motor_pod_diameter_m: float  # diameter of the motor pod under each rotor, m


@dataclass(frozen=True)
class DownwashSpec:
    """Velocity-field parameters of this vehicle as a downwash *source* (S0-1, S0-2)."""

    c_ax: float  # axial decay constant, -
    z0_m: float  # virtual origin below the rotor plane, m
    c_rad: float  # radial (Gaussian) decay rate, -


@dataclass(frozen=True)
class Vehicle:
    """A quadrotor in X configuration with (S0-14) motor numbering."""

    name: str
    mass_kg: float
    arm_length_m: float  # centre of mass to each motor axis, m
    max_thrust_N: float  # all motors together, N
    inertia_diag_kgm2: tuple[float, float, float]  # principal inertia (Jxx, Jyy, Jzz), kg m^2
    torque_to_thrust_m: float  # k_t of (S0-14c): yaw torque per unit thrust, m
    propeller: PropellerSpec
    frame: FrameSpec
    downwash: DownwashSpec
    rotor_drag: RotorDrag  # per-rotor drag coefficients (proxplan.physics.rotor_drag)
    controller: ControllerGains  # the gains the vehicle flies with (proxplan.physics.controller_gains)
    min_motor_thrust_N: float = 0.0  # lowest thrust one motor can hold, N
    kinematics: KinematicLimits | None = None  # trackable limits; None: derived, see kinematic_limits
    motor_time_constant_s: float = DEFAULT_MOTOR_TIME_CONSTANT_S  # first-order motor lag, s
    tracking: TrackingMeasurement | None = None  # how ``kinematics`` and the tube were measured
    description: str = ""
    sources: dict[str, str] = field(default_factory=dict, compare=False, hash=False)

    @property
    def n_rotors(self) -> int:
        return 4

    @property
    def size_m(self) -> float:
        """Vehicle size L = 2 x arm length (S0 II-A), m."""
        return 2.0 * self.arm_length_m

    @property
    def body_radius_m(self) -> float:
        """Radius of the disc that holds frame and propellers: arm length + propeller radius, m."""
        return self.arm_length_m + self.propeller.radius_m

    @cached_property
    def kinematic_limits(self) -> KinematicLimits:
        """Speed, acceleration and jerk limits: ``kinematics`` when given, else derived from the
        spare vertical acceleration a = T_max/m - g: accel = a/4 clipped to [0.25, 1] m/s^2,
        speed 1 m/s, jerk 2 x accel (conservative caps for an unmeasured vehicle; measure yours
        with ``proxplan track-limits``, docs/flying.md)."""
        if self.kinematics is not None:
            return self.kinematics
        spare_mps2 = self.max_thrust_N / self.mass_kg - GRAVITY_MPS2
        accel = float(min(1.0, max(0.25, 0.25 * spare_mps2)))
        return KinematicLimits(max_speed_mps=1.0, max_accel_mps2=accel, max_jerk_mps3=2.0 * accel)

    @property
    def tracking_tube_m(self) -> float:
        """Tracking tube of this type, m: how far it may fly off its plan (measured quantile of the
        closed-loop error + margin, :class:`TrackingMeasurement`), else :data:`DEFAULT_TRACKING_TUBE_M`."""
        return self.tracking.tube_m if self.tracking is not None else DEFAULT_TRACKING_TUBE_M

    @property
    def weight_N(self) -> float:
        return self.mass_kg * GRAVITY_MPS2

    @property
    def hover_thrust_per_rotor_N(self) -> float:
        return self.weight_N / self.n_rotors

    @property
    def max_thrust_per_rotor_N(self) -> float:
        return self.max_thrust_N / self.n_rotors

    @property
    def hover_omega_sq_rad2ps2(self) -> float:
        """omega^2 at hover, f_hover / k1 (S0-5), rad^2/s^2."""
        return self.hover_thrust_per_rotor_N / self.propeller.k1_Ns2prad2

    @property
    def hover_omega_radps(self) -> float:
        """Rotor speed at hover, rad/s."""
        return math.sqrt(self.hover_omega_sq_rad2ps2)

    @property
    def drag_rate_ps(self) -> np.ndarray:
        """Rotor-drag acceleration per m/s near hover per world axis (x, y, z), 1/s: c = n omega_hover
        (k_d, k_d, k_z) / m (:func:`proxplan.physics.rotor_drag.drag_rate_ps`)."""
        return drag_rate_ps(self.rotor_drag, self.n_rotors, self.hover_omega_radps, self.mass_kg)

    @cached_property
    def rotor_positions_m(self) -> np.ndarray:
        """Rotor hub positions in the body frame, (S0-14) order, shape (4, 3), m (read-only)."""
        xy = MOTOR_DIRECTIONS_XY * (self.arm_length_m / math.sqrt(2.0))
        positions = np.column_stack([xy, np.zeros(4)])
        positions.setflags(write=False)
        return positions

    @cached_property
    def b_v(self) -> float:
        """Thrust decay coefficient b_v (S0-5), N m^-1 rad^-2 s^3: measured, else from S1 theory."""
        if self.propeller.b_v_measured is not None:
            return self.propeller.b_v_measured
        return derived_b_v(self.propeller, hover_thrust_N=self.hover_thrust_per_rotor_N)

    def to_dict(self) -> dict:
        """Every parameter with its unit-suffixed name, for JSON output and map metadata."""
        p, f, d = self.propeller, self.frame, self.downwash
        return {
            "name": self.name,
            "description": self.description,
            "mass_kg": self.mass_kg,
            "arm_length_m": self.arm_length_m,
            "size_L_m": self.size_m,
            "max_thrust_N": self.max_thrust_N,
            "min_motor_thrust_N": self.min_motor_thrust_N,
            "inertia_diag_kgm2": list(self.inertia_diag_kgm2),
            "torque_to_thrust_m": self.torque_to_thrust_m,
            "propeller": {
                "diameter_m": p.diameter_m,
                "chord_m": p.chord_m,
                "pitch_m": p.pitch_m,
                "n_blades": p.n_blades,
                "thrust_coefficient": p.thrust_coefficient,
                "lift_slope_per_rad": p.lift_slope_per_rad,
                "tip_loss_factor": p.tip_loss_factor,
                "k1_Ns2prad2": p.k1_Ns2prad2,
                "b_v_Nsm3prad2": self.b_v,
                "b_v_source": "measured" if p.b_v_measured is not None else "blade-element (S1-4..8)",
            },
            "frame": {
                "hub_side_m": f.hub_side_m,
                "arm_width_m": f.arm_width_m,
                "motor_pod_diameter_m": f.motor_pod_diameter_m,
            },
            "downwash": {"c_ax": d.c_ax, "z0_m": d.z0_m, "c_rad": d.c_rad},
            "kinematic_limits": {
                "max_speed_mps": self.kinematic_limits.max_speed_mps,
                "max_accel_mps2": self.kinematic_limits.max_accel_mps2,
                "max_jerk_mps3": self.kinematic_limits.max_jerk_mps3,
                "source": "given" if self.kinematics is not None else "derived from thrust-to-weight",
            },
            "tracking_tube_m": self.tracking_tube_m,
            "tracking": dataclasses.asdict(self.tracking) if self.tracking is not None else None,
            "motor_time_constant_s": self.motor_time_constant_s,
            "rotor_drag": {**dataclasses.asdict(self.rotor_drag), "drag_rate_ps": self.drag_rate_ps.tolist()},
            "controller": dataclasses.asdict(self.controller),
            "hover_thrust_per_rotor_N": self.hover_thrust_per_rotor_N,
            "sources": dict(self.sources),
        }
