"""Measurement-level synthetic flight logs with a known truth, for tests of ``proxplan identify``.

No rigid-body simulation: every vehicle follows a scripted trajectory and its motors cancel the
truth wrench exactly. Closed-loop synthetic flights come from :mod:`flightsim`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from proxplan.identify.vehicle_log import VehicleLog


@dataclass(frozen=True)
class SyntheticMotor:
    """A firmware-like motor: delivered thrust P(x) = c1 x + c2 x^2 (N) of x = pwm * Vbat (V), within
    0..``ceiling_N`` (the lower of ``max_thrust_N`` and what the top PWM ``pwm_max`` gives at the
    battery's voltage: a low battery lowers the ceiling). Past either limit the desired u[N] runs on by
    ``windup`` times the shortfall: above the ceiling, and below zero (PWM 0, the motor off) when the
    controller asks for a negative force."""

    c1_NpV: float = 0.01
    c2_NpV2: float = 0.01
    max_thrust_N: float = 0.144  # per motor, N (Crazyflie 2.1 class)
    windup: float = 3.0  # -
    vbat_start_V: float = 4.1
    vbat_end_V: float = 3.6
    pwm_max: float = 1.0  # top PWM (normalised), -

    def thrust_N(self, x_V: np.ndarray) -> np.ndarray:
        return self.c1_NpV * x_V + self.c2_NpV2 * x_V**2

    def ceiling_N(self, vbat_V: np.ndarray) -> np.ndarray:
        """Most a motor delivers at battery voltages ``vbat_V`` (N,), N."""
        return np.minimum(self.max_thrust_N, self.thrust_N(self.pwm_max * np.asarray(vbat_V)))

    def pwm_of(self, thrust_N: np.ndarray, vbat_V: np.ndarray) -> np.ndarray:
        """PWM (0..1) that makes ``thrust_N`` (N, 4) at battery voltages ``vbat_V`` (N,)."""
        f = np.clip(thrust_N, 0.0, None)
        x = (-self.c1_NpV + np.sqrt(self.c1_NpV**2 + 4.0 * self.c2_NpV2 * f)) / (2.0 * self.c2_NpV2)
        return x / vbat_V[:, None]


def synthetic_logs(
    vehicles: Mapping[str, Any],
    positions_m: Mapping[str, np.ndarray],
    t_s: np.ndarray,
    *,
    effects: tuple = (),
    ground_z_m: float = 0.0,
    accel_noise_mps2: float = 0.0,
    seed: int = 0,
    hidden_wrench: Callable[[Any], tuple[np.ndarray, np.ndarray]] | None = None,
    motor_noise_N: float = 0.0,
    motor: SyntheticMotor | None = None,
    motor_time_constant_s: float | None = None,
    planes: tuple = (),
) -> dict[str, VehicleLog]:
    """Logs with a known truth: every vehicle follows ``positions_m[name]`` (N, 3), m, level, and
    receives the wrench of :func:`proxplan.physics.effects.total_wrench` (base model from all other vehicles
    plus ``effects``). Its controller cancels the wrench exactly: motor thrusts from the (S0-14) mixer
    give collective m (g + a_z) - F_z and body torque -tau, and the accelerometer (world, specific
    force) reads (T z + F) / m plus white noise ``accel_noise_mps2``. So the S0-11/S0-13 measurement
    returns the truth wrench (up to noise and smoothing). Gyro zero (level, no yaw rate).

    With ``motor`` the logs also hold PWM and Vbat (:class:`SyntheticMotor`) and the motors meet
    their limits: each delivers the demand clipped to 0..ceiling (the ceiling falls with the battery),
    the accelerometer sees the DELIVERED thrust, and the logged u[N] is the firmware-like desired force,
    which runs on past the ceiling and below zero (PWM 0).

    This is a measurement-level generator (no rigid-body simulation): for closed-loop flights use
    the simulator (flightsim).

    ``hidden_wrench(inputs)`` (optional) adds a wrench no library effect names (force (N, 3) N,
    torque (N, 3) N m, world) from the :class:`proxplan.physics.effect_inputs.EffectInputs` of each vehicle (with
    ``time_s``, the sources' velocities, the target's thrust and position and the room's ``planes``
    filled in): a truth for the tests
    of :mod:`proxplan.identify.discovery`. ``motor_noise_N`` adds white noise to each logged motor thrust
    (N), which reaches the measured force and torque.

    With ``motor_time_constant_s`` (s) the logged motor thrusts are the COMMANDS that first-order
    motors with that lag turn into the needed thrusts (:func:`proxplan.identify.measure.motor_command_for_N`),
    as a real flight controller logs them (manifest ``motor_thrust: commanded``).
    """
    from proxplan.physics import GRAVITY_MPS2, EffectInputs, SourceSample, mixer_matrix, total_wrench

    rng = np.random.default_rng(seed)
    n = len(t_s)
    out = {}
    vels = {k: np.gradient(np.asarray(p, dtype=float), t_s, axis=0) for k, p in positions_m.items()}
    for name, veh in vehicles.items():
        pos = np.asarray(positions_m[name], dtype=float)
        vel = vels[name]
        acc = np.gradient(vel, t_s, axis=0)
        inputs = EffectInputs(
            target=veh,
            height_above_ground_m=pos[:, 2] - ground_z_m,
            velocity_mps=vel,
            sources=tuple(
                SourceSample(vehicles[o], pos - np.asarray(positions_m[o]), vels[o]) for o in vehicles if o != name
            ),
            time_s=np.asarray(t_s, dtype=float),
            thrust_z_N=veh.mass_kg * (GRAVITY_MPS2 + acc[:, 2]),
            position_m=pos,
            planes=tuple(planes),
        )
        force, torque = total_wrench(inputs, tuple(effects))
        if hidden_wrench is not None:
            hf, ht = hidden_wrench(inputs)
            force, torque = force + hf, torque + ht
        collective = veh.mass_kg * (GRAVITY_MPS2 + acc[:, 2]) - force[:, 2]
        demand = np.column_stack([collective, -torque[:, 0], -torque[:, 1], -torque[:, 2]])
        thrusts = np.linalg.solve(mixer_matrix(veh), demand.T).T
        pwm = vbat = None
        if motor_time_constant_s is not None:
            from proxplan.identify.measure import motor_command_for_N

            thrusts = motor_command_for_N(thrusts, float(np.median(np.diff(t_s))), motor_time_constant_s)
        logged = thrusts
        if motor is not None:
            vbat = np.linspace(motor.vbat_start_V, motor.vbat_end_V, n)
            cap = motor.ceiling_N(vbat)[:, None]
            delivered = np.clip(thrusts, 0.0, cap)
            logged = thrusts + motor.windup * (thrusts - delivered)  # runs on past the ceiling and below zero
            pwm = motor.pwm_of(delivered, vbat)
            collective = delivered.sum(axis=1)  # what the motors give (level flight: along world z)
        spec = force.copy()
        spec[:, 2] += collective
        spec = spec / veh.mass_kg + rng.normal(0.0, accel_noise_mps2, (n, 3))
        out[name] = VehicleLog(
            t_s=np.asarray(t_s, dtype=float),
            position_m=pos,
            velocity_mps=vel,
            accel_mps2=spec,
            quat_xyzw=np.tile([0.0, 0.0, 0.0, 1.0], (n, 1)),
            motor_thrust_N=logged + (rng.normal(0.0, motor_noise_N, (n, 4)) if motor_noise_N > 0.0 else 0.0),
            gyro_radps=np.zeros((n, 3)),
            source=f"synthetic:{name}",
            motor_pwm=pwm,
            vbat_V=vbat,
        )
    return out


def write_synthetic_manifest(
    root: Path,
    flights: Sequence[tuple[str, str, Mapping[str, VehicleLog]]],
    vehicle_type: str | Mapping[str, str],
    *,
    motor_thrust: str = "delivered",
    planes: Sequence[Mapping[str, Any]] = (),
) -> Path:
    """Write every flight ``(name, split, {vehicle: log})`` as canonical gzip CSVs under ``root``
    (``<flight>_<vehicle>.csv.gz``) and a canonical manifest ``root/manifest.yaml`` naming them,
    every vehicle of type ``vehicle_type`` (or ``vehicle_type[vehicle]``), whose motor thrust columns
    hold ``motor_thrust`` (commanded or delivered), declaring the room's ``planes`` ({name, point_m,
    normal}); returns the manifest path."""
    import yaml

    from proxplan.identify.vehicle_log import write_canonical_csv

    entries = []
    for name, split, logs in flights:
        entry: dict[str, Any] = {"name": name, "split": split, "vehicles": {}}
        for vehicle, log in logs.items():
            write_canonical_csv(log, root / f"{name}_{vehicle}.csv.gz")
            vtype = vehicle_type if isinstance(vehicle_type, str) else vehicle_type[vehicle]
            entry["vehicles"][vehicle] = {"type": vtype, "log": f"{name}_{vehicle}.csv.gz"}
        entries.append(entry)
    path = root / "manifest.yaml"
    doc: dict[str, Any] = {"format": "canonical", "root": ".", "motor_thrust": motor_thrust, "flights": entries}
    if planes:
        doc["planes"] = [dict(p) for p in planes]
    path.write_text(yaml.safe_dump(doc))
    return path
