"""What a simulated flight is asked to do: :class:`SimulationOptions` (rates, noise, controller,
compensations) and :class:`Perturbation` (per-flight departures of the world from the plan, drawn by
``proxplan certify``)."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np

from proxplan.flightsim.imu import ImuOptions
from proxplan.physics import FIRMWARE_SETPOINT_RATE_HZ

CONTROLLERS = ("mellinger", "rotorpy")
"""Names of the simulated tracking controllers (``SimulationOptions.controller``)."""


@dataclass(frozen=True)
class SimulationOptions:
    physics_dt_s: float = 0.002  # RK4 step of the dynamics and controller period, s
    log_dt_s: float = 0.01  # log / record period, s (a multiple of physics_dt_s)
    settle_s: float = 1.0  # hover at the final reference after the plan ends, s
    wrench_horizon_steps: int = 10  # physics steps per batched wrench evaluation, -
    imu_noise: bool = True  # white noise on the logged IMU samples
    imu: ImuOptions = ImuOptions()
    mocap_noise_std_m: float = 0.0005  # noise of the logged positions, m
    velocity_noise_std_mps: float = 0.005  # noise of the logged velocities, m/s
    ground_z_m: float = 0.0  # ground plane height, world frame, m
    seed: int = 0
    position_integral_rate_ps: float = 0.0  # integral action k_i / k_p per axis, 1/s (0 = RotorPy's PD)
    position_integral_limit_ms: float = 0.2  # anti-windup bound of the integrated position error, m s
    feedforward: bool = False  # compensate the plan's predicted disturbance wrench in the controller
    controller: str = "mellinger"  # "mellinger" (Crazyflie firmware law) or "rotorpy" (RotorPy's SE(3))
    rate_feedforward: bool = True  # Mellinger: body-rate feed-forward from the reference jerk
    setpoint_rate_hz: float = FIRMWARE_SETPOINT_RATE_HZ  # Mellinger: set-point evaluation rate (held in between), Hz
    drag_compensation: bool = True  # fly plan + drag lead (what the export uploads), proxplan.planfile.reference


@dataclass(frozen=True)
class Perturbation:
    """Per-flight departures of the flown world from the plan (``proxplan certify`` draws them),
    keyed by vehicle name; vehicles not named fly unperturbed. Functions take times since the plan
    start (K,), s, and return (K, 3) arrays, world frame.

    * ``start_offset_m``: start position error, m (the vehicle starts off its reference);
    * ``time_offset_s``: timing error, s: the vehicle follows its plan late by this (early if < 0);
    * ``force_N``: residual disturbance force beyond the model, N (applied and counted in the
      applied wrench, so authority usage includes it);
    * ``estimate_error_m`` / ``estimate_error_mps``: error of the position / velocity estimate the
      controller sees, m and m/s. The controllers use only x - x_ref and v - v_ref, so an estimate
      x + n is flown exactly as the reference x_ref - n, which is how it is applied;
    * ``wrench_of_state``: a residual wrench that depends on the flown state, or None. Called once per wrench
      horizon (``SimulationOptions.wrench_horizon_steps``), in time order, as ``f(t_s, position_m, velocity_mps,
      acceleration_mps2)`` with the horizon's times since the plan start (K,), s, and every vehicle's state
      predicted over it (K, V, 3), world frame, m, m/s, m/s^2 (vehicles in the plan's order); returns the force
      (K, V, 3), N, and the torque (K, V, 3), N m, world axes about the vehicle's centre of mass (the model's
      wrench convention), added to the applied wrench (the force beside ``force_N``'s; applied and counted
      alike). A callable that needs the past (a delay) keeps it from its earlier calls.
    """

    start_offset_m: Mapping[str, Sequence[float]] = field(default_factory=dict)
    time_offset_s: Mapping[str, float] = field(default_factory=dict)
    force_N: Mapping[str, Callable[[np.ndarray], np.ndarray]] = field(default_factory=dict)
    estimate_error_m: Mapping[str, Callable[[np.ndarray], np.ndarray]] = field(default_factory=dict)
    estimate_error_mps: Mapping[str, Callable[[np.ndarray], np.ndarray]] = field(default_factory=dict)
    wrench_of_state: (
        Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]] | None
    ) = None
