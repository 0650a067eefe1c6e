"""What a simulated flight returns: per-vehicle records (:class:`VehicleRecord`), the result
(:class:`SimulationResult`, :class:`SimulationStatus`), and the recorder the flight loop fills
(:class:`FlightLog`)."""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from proxplan.flightsim.options import SimulationOptions
from proxplan.flightsim.truth import TruthSpec
from proxplan.physics import Vehicle


@dataclass(frozen=True)
class VehicleRecord:
    """One vehicle's flight sampled every ``log_dt_s`` (M samples). World frame unless noted."""

    name: str
    type_name: str
    vehicle: Vehicle
    t_s: np.ndarray  # (M,) since the plan start, s
    position_m: np.ndarray  # (M, 3) true
    velocity_mps: np.ndarray  # (M, 3) true
    acceleration_mps2: np.ndarray  # (M, 3) true (gravity excluded)
    q_xyzw: np.ndarray  # (M, 4) body to world
    w_body_radps: np.ndarray  # (M, 3) true body rates, body frame
    ref_position_m: np.ndarray  # (M, 3) the plan (errors are measured against it)
    ref_velocity_mps: np.ndarray  # (M, 3) the plan's
    motor_thrust_N: np.ndarray  # (M, 4) actual k_eta omega^2, (S0-14) order
    cmd_motor_thrust_N: np.ndarray  # (M, 4) commanded by the controller (unclipped)
    cmd_thrust_N: np.ndarray  # (M,) commanded collective thrust
    cmd_moment_Nm: np.ndarray  # (M, 3) commanded body moments, body frame
    saturated: np.ndarray  # (M,) bool: a motor command was clipped at this sample
    accel_meas_body_mps2: np.ndarray  # (M, 3) IMU specific force, body frame
    gyro_meas_radps: np.ndarray  # (M, 3) IMU gyro, body frame
    applied_force_N: np.ndarray  # (M, 3) external force applied (model + truth effects)
    applied_torque_Nm: np.ndarray  # (M, 3) external torque applied, world axes
    model_force_N: np.ndarray  # (M, 3) base model part only (no truth effects)
    model_torque_Nm: np.ndarray  # (M, 3)
    predicted_force_N: np.ndarray | None = None  # (M, 3) the plan's predicted disturbance, world frame, N
    predicted_torque_Nm: np.ndarray | None = None  # (M, 3) world axes, N m
    setpoint_position_m: np.ndarray | None = None  # (M, 3) the position set-point the controller was given, m
    predicted_deflection_m: np.ndarray | None = None  # (M,) how far the plan predicts it beyond its tube, m
    # (proxplan.verify.predicted_tube_growth: its tracking error and its loop in the jets, the hold after the end)
    tube_m: float | None = None  # the tube the verifier grants it (limits.tracking_margin_m; None: its type's), m

    @property
    def accel_meas_world_mps2(self) -> np.ndarray:
        """IMU specific force rotated into the world frame (M, 3), m/s^2 (~ +9.81 on z in hover)."""
        from scipy.spatial.transform import Rotation

        return Rotation.from_quat(self.q_xyzw).apply(self.accel_meas_body_mps2)


class SimulationStatus(enum.Enum):
    """How a simulation ended (a result, like RotorPy's ExitStatus; not a user error)."""

    COMPLETE = "complete"  # flown to the end of the plan plus settle_s
    DIVERGED = "diverged"  # a vehicle's state became non-finite: it lost control; records stop before


@dataclass(frozen=True)
class SimulationResult:
    scenario: str
    options: SimulationOptions
    truth: TruthSpec
    plan_duration_s: float  # the plan's own duration; records run settle_s longer, s
    records: dict[str, VehicleRecord]
    saturation_time_s: dict[str, float]  # physics-step time with any motor command clipped, s
    wall_time_s: float
    sim_time_s: float
    notes: list[str] = field(default_factory=list)
    status: SimulationStatus = SimulationStatus.COMPLETE
    status_detail: str = ""  # what ended the flight when it did not complete
    max_lead_m: dict[str, float] = field(default_factory=dict)  # largest drag lead of each set-point, m

    @property
    def real_time_factor(self) -> float:
        return self.sim_time_s / max(self.wall_time_s, 1e-9)


LOGGED = {
    "position_m": (3,),  # position, m
    "velocity_mps": (3,),  # velocity, m/s
    "acceleration_mps2": (3,),  # acceleration, m/s^2
    "q_xyzw": (4,),  # attitude [x, y, z, w]
    "w_body_radps": (3,),  # body rates, rad/s
    "ref_position_m": (3,),  # the plan's position, m
    "ref_velocity_mps": (3,),  # the plan's velocity, m/s
    "setpoint_position_m": (3,),  # the position set-point, m
    "motor_thrust_N": (4,),  # motor thrusts, N
    "cmd_motor_thrust_N": (4,),  # commanded motor thrusts, N
    "cmd_thrust_N": (),  # collective thrust command, N
    "cmd_moment_Nm": (3,),  # moment command, N m
    "accel_meas_body_mps2": (3,),  # IMU specific force, m/s^2
    "gyro_meas_radps": (3,),  # IMU gyro, rad/s
    "applied_force_N": (3,),  # applied force, N
    "applied_torque_Nm": (3,),  # applied torque, N m
    "model_force_N": (3,),  # base-model force, N
    "model_torque_Nm": (3,),  # base-model torque, N m
}
"""Arrays of :class:`FlightLog`, named as the :class:`VehicleRecord` fields they fill -> shape per
vehicle and sample."""


class FlightLog:
    """The arrays a flight fills every log step, (n_log, V, ...) each (:data:`LOGGED`), and the
    saturated flags (n_log, V)."""

    def __init__(self, n_log: int, n_vehicles: int):
        self.arrays = {key: np.zeros((n_log, n_vehicles) + shape) for key, shape in LOGGED.items()}
        self.saturated = np.zeros((n_log, n_vehicles), dtype=bool)

    def put(self, i: int, **values: np.ndarray) -> None:
        """Store row ``i`` of the named arrays."""
        for key, value in values.items():
            self.arrays[key][i] = value

    def truncate(self, n: int) -> None:
        """Keep the first ``n`` rows (a diverged flight keeps its finite part)."""
        self.arrays = {key: arr[:n] for key, arr in self.arrays.items()}
        self.saturated = self.saturated[:n]

    def record(self, vi: int, name: str, type_name: str, vehicle: Vehicle, t_s: np.ndarray, **extra) -> VehicleRecord:
        """Vehicle ``vi``'s :class:`VehicleRecord` (``extra``: the optional fields)."""
        logged: dict[str, Any] = {key: arr[:, vi] for key, arr in self.arrays.items()}
        return VehicleRecord(
            name=name,
            type_name=type_name,
            vehicle=vehicle,
            t_s=t_s,
            saturated=self.saturated[:, vi],
            **logged,
            **extra,
        )
