"""The log contract: what identify needs from any flight log, and the firmware names that hold it.

Every format reader (uSD, ROS 2 bag, PX4 ULog) hands its columns to :func:`vehicle_log` under
CONTRACT names; :data:`CRAZYFLIE_VARIABLES` is the table from the Crazyflie firmware's log variables
to them, and a manifest's ``variables:`` mapping overrides any entry (contract name -> log name).

Units and frames, and the conversion each contract entry gets (to :class:`VehicleLog`'s SI, world
frame z up, body frame x forward / z up):

=================  ==========================  ==================================================
contract           Crazyflie variable          conversion
=================  ==========================  ==================================================
x, y, z            stateEstimate.x/y/z (m)     none: position, world frame
vx, vy, vz         stateEstimate.vx/vy/vz      none: velocity, m/s, world frame
qx, qy, qz, qw     stateEstimate.qx..qw        none: attitude body -> world, scalar last
acc_x..acc_z       acc.x/y/z (g, body)         x 9.80665 m/s^2 per g, rotated body -> world by q:
                                               the specific force, +9.81 m/s^2 on z in hover
gyro_x..gyro_z     gyro.x/y/z (deg/s, body)    x pi/180 -> rad/s, body frame
m1..m4             motor.m1..m4 (PWM counts)   / 65536 -> normalised PWM 0..1 (motor order of the
                                               Crazyflie = (S0-14): 1 (+x,-y), 2 (-x,-y), 3 (-x,+y), 4 (+x,+y))
vbat               pm.vbat (V)                 none
=================  ==========================  ==================================================

No force is in the contract: :mod:`proxplan.identify.pwm_thrust` turns PWM and battery voltage into
each motor's thrust (``VehicleLog.thrust_logged`` False); until then ``motor_thrust_N`` holds the base
map's force at scale 1 (for the quality checks' idle-motor test).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from proxplan.fileio import UserError
from proxplan.identify.vehicle_log import VehicleLog

G0_MPS2 = 9.80665
"""Standard gravity: one g of the accelerometer's unit, m/s^2 (the definition of the unit)."""
DEG = np.pi / 180.0
"""Radians per degree."""

CONTRACT = (
    "x", "y", "z", "vx", "vy", "vz", "qx", "qy", "qz", "qw",
    "acc_x", "acc_y", "acc_z", "gyro_x", "gyro_y", "gyro_z", "m1", "m2", "m3", "m4", "vbat",
)  # fmt: skip
"""Every name of the log contract, in this order."""

CRAZYFLIE_VARIABLES = {
    "x": "stateEstimate.x", "y": "stateEstimate.y", "z": "stateEstimate.z",
    "vx": "stateEstimate.vx", "vy": "stateEstimate.vy", "vz": "stateEstimate.vz",
    "qx": "stateEstimate.qx", "qy": "stateEstimate.qy", "qz": "stateEstimate.qz", "qw": "stateEstimate.qw",
    "acc_x": "acc.x", "acc_y": "acc.y", "acc_z": "acc.z",
    "gyro_x": "gyro.x", "gyro_y": "gyro.y", "gyro_z": "gyro.z",
    "m1": "motor.m1", "m2": "motor.m2", "m3": "motor.m3", "m4": "motor.m4",
    "vbat": "pm.vbat",
}  # fmt: skip
"""Contract name -> Crazyflie firmware log variable (uSD deck, cflib, Crazyswarm2 LogDataGeneric)."""


def stream_summary(name: str, t_s: np.ndarray, variables: Sequence[str]) -> dict[str, Any]:
    """One event / topic / CSV: its variables, samples, median rate (Hz), time span (s)."""
    t = np.asarray(t_s, dtype=float)
    dt = float(np.median(np.diff(t))) if t.size > 1 else float("nan")
    return {"name": name, "variables": list(variables), "samples": int(t.size),
            "rate_hz": (1.0 / dt) if dt > 0 else None,
            "start_s": float(t[0]) if t.size else None, "duration_s": float(t[-1] - t[0]) if t.size else 0.0}  # fmt: skip


def variable_table(overrides: Mapping[str, str] | None, where: str) -> dict[str, str]:
    """:data:`CRAZYFLIE_VARIABLES` with a manifest's ``variables:`` overrides (contract name -> log name)."""
    table = dict(CRAZYFLIE_VARIABLES)
    for key, name in (overrides or {}).items():
        if key not in CONTRACT:
            raise UserError(f"{where}: variables.{key}: unknown contract name; expected one of {', '.join(CONTRACT)}")
        table[key] = str(name)
    return table


def missing_variables(available: set[str], table: Mapping[str, str]) -> list[str]:
    """Contract entries whose log name is not in ``available``, as ``contract (log name)``."""
    return [f"{k} ({table[k]})" for k in CONTRACT if table[k] not in available]


def vehicle_log(
    t_s: np.ndarray,
    columns: Mapping[str, np.ndarray],
    *,
    source: str,
    thrust_shape: str = "foerster2015",
    pwm_scale: float = 1.0 / 65536.0,
    acc_scale: float = G0_MPS2,
    acc_frame: str = "body",
    gyro_scale: float = DEG,
) -> VehicleLog:
    """A :class:`VehicleLog` from contract ``columns`` (each (N,), firmware units, see the module table).

    ``pwm_scale`` turns the motor entries into normalised PWM (0..1); ``acc_scale`` the acceleration into
    m/s^2 of specific force (``acc_frame`` ``body``: rotated to world by the quaternion); ``gyro_scale`` the
    gyro into rad/s. The quaternion is normalised (a logged one carries float rounding).
    """
    from scipy.spatial.transform import Rotation

    from proxplan.identify.pwm_thrust import base_map

    def stack(*keys: str) -> np.ndarray:
        return np.column_stack([np.asarray(columns[k], dtype=float) for k in keys])

    quat = stack("qx", "qy", "qz", "qw")
    norm = np.linalg.norm(quat, axis=1, keepdims=True)
    bad = ~(norm[:, 0] > 0.5)  # a zero / NaN quaternion: the row is dropped by the checks (NaN)
    quat = np.where(bad[:, None], np.nan, quat / np.where(norm > 0, norm, 1.0))
    acc = stack("acc_x", "acc_y", "acc_z") * acc_scale
    if acc_frame == "body":
        ok = ~bad
        world = np.full_like(acc, np.nan)
        world[ok] = Rotation.from_quat(quat[ok]).apply(acc[ok])
        acc = world
    pwm = stack("m1", "m2", "m3", "m4") * pwm_scale
    vbat = np.asarray(columns["vbat"], dtype=float)
    return VehicleLog(
        t_s=np.asarray(t_s, dtype=float),
        position_m=stack("x", "y", "z"),
        velocity_mps=stack("vx", "vy", "vz"),
        accel_mps2=acc,
        quat_xyzw=quat,
        motor_thrust_N=base_map(thrust_shape).thrust_N(pwm, vbat),
        gyro_radps=stack("gyro_x", "gyro_y", "gyro_z") * gyro_scale,
        source=source,
        motor_pwm=pwm,
        vbat_V=vbat,
        thrust_logged=False,
        thrust_shape=thrust_shape,
    )


def firmware_columns(log: VehicleLog) -> dict[str, tuple[str, np.ndarray]]:
    """The inverse of :func:`vehicle_log`: ``log``'s samples as the Crazyflie firmware logs them,
    {firmware variable: (struct type character, values (N,))} in firmware units (floats as float32,
    motor PWM as uint32 counts 0..65535, acc in g in the body frame, gyro in deg/s). No force: the
    firmware logs none. For writing test files and rewriting other logs as uSD logs."""
    from scipy.spatial.transform import Rotation

    if log.motor_pwm is None or log.vbat_V is None:
        raise UserError(f"{log.source}: no motor PWM and battery voltage: the firmware's log contract needs both")
    body_g = Rotation.from_quat(log.quat_xyzw).inv().apply(log.accel_mps2) / G0_MPS2
    counts = np.clip(np.round(log.motor_pwm * 65536.0), 0, 65535).astype(np.int64)
    values = {
        "x": log.position_m[:, 0], "y": log.position_m[:, 1], "z": log.position_m[:, 2],
        "vx": log.velocity_mps[:, 0], "vy": log.velocity_mps[:, 1], "vz": log.velocity_mps[:, 2],
        "qx": log.quat_xyzw[:, 0], "qy": log.quat_xyzw[:, 1], "qz": log.quat_xyzw[:, 2], "qw": log.quat_xyzw[:, 3],
        "acc_x": body_g[:, 0], "acc_y": body_g[:, 1], "acc_z": body_g[:, 2],
        "gyro_x": log.gyro_radps[:, 0] / DEG, "gyro_y": log.gyro_radps[:, 1] / DEG, "gyro_z": log.gyro_radps[:, 2] / DEG,
        "m1": counts[:, 0], "m2": counts[:, 1], "m3": counts[:, 2], "m4": counts[:, 3], "vbat": log.vbat_V,
    }  # fmt: skip
    return {CRAZYFLIE_VARIABLES[k]: ("I" if k.startswith("m") else "f", np.asarray(v)) for k, v in values.items()}
