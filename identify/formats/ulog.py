"""PX4 ULog files through ``pyulog``.

Topics (the first instance of each) and their conversion to :class:`VehicleLog` (PX4 frames: world NED,
body FRD; ours: world z up, body z up — both turned by 180 deg about x, (a, b, c) -> (a, -b, -c), so x
stays north / forward):

* ``vehicle_local_position`` x, y, z (m, NED) and vx, vy, vz (m/s, NED) -> position and velocity; its
  clock is the log's clock (the others are interpolated onto it linearly);
* ``vehicle_attitude`` q = (w, x, y, z), FRD body -> NED world -> our quaternion (x, -y, -z, w), scalar
  last (the same rotation conjugated by the 180 deg turn);
* ``vehicle_angular_velocity`` xyz (rad/s, FRD) -> gyro (rad/s, body z up);
* ``sensor_combined`` accelerometer_m_s2 (FRD, specific force: -9.81 on z in hover) or, without it,
  ``vehicle_acceleration`` xyz -> specific force in the body frame, rotated to the world frame;
* ``actuator_motors`` control[0..3] (normalised motor command 0..1, motor order of the mixer: check it
  is (S0-14)'s) -> the motor commands; thrust through PX4's own thrust model with the log's
  ``THR_MDL_FAC`` parameter (0 when absent): relative thrust fac c^2 + (1 - fac) c, scaled per type in
  free flight (:mod:`proxplan.identify.pwm_thrust`);
* ``battery_status`` voltage_v (V) -> reported (``proxplan logs``); PX4 compensates the battery in
  its thrust command (MC_BAT_SCALE_EN), so the thrust model takes the command alone (``vbat`` = 1).

Timestamps are microseconds since boot: several vehicles need the manifest's ``time_offset_s`` (or an
alignment on the motion-capture track) to share a clock.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from proxplan.fileio import UserError
from proxplan.identify.vehicle_log import VehicleLog

TOPICS = {
    "vehicle_local_position": ("x", "y", "z", "vx", "vy", "vz"),
    "vehicle_attitude": ("q[0]", "q[1]", "q[2]", "q[3]"),
    "vehicle_angular_velocity": ("xyz[0]", "xyz[1]", "xyz[2]"),
    "sensor_combined": ("accelerometer_m_s2[0]", "accelerometer_m_s2[1]", "accelerometer_m_s2[2]"),
    "vehicle_acceleration": ("xyz[0]", "xyz[1]", "xyz[2]"),
    "actuator_motors": ("control[0]", "control[1]", "control[2]", "control[3]"),
    "battery_status": ("voltage_v",),
}
"""Topic -> fields read (pyulog flattens arrays as ``name[k]``)."""
REQUIRED = ("vehicle_local_position", "vehicle_attitude", "vehicle_angular_velocity", "actuator_motors")
"""Topics without which a ULog cannot be identified (plus sensor_combined or vehicle_acceleration)."""


def _open(path: Path):
    from pyulog import ULog

    try:
        return ULog(str(path), list(TOPICS))
    except FileNotFoundError:
        raise UserError(f"{path}: log file not found") from None
    except Exception as err:  # pyulog raises plain exceptions on a malformed file
        raise UserError(
            f"{path}: not a readable PX4 ULog ({str(err).splitlines()[0] if str(err) else type(err).__name__})"
        ) from None


def _topics(ulog) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for d in sorted(ulog.data_list, key=lambda d: d.multi_id):
        out.setdefault(d.name, d)
    return out


def read_ulog(path: str | Path) -> VehicleLog:
    """One vehicle's ULog as a :class:`VehicleLog` (module docstring); UserError naming a missing topic."""
    from proxplan.identify.formats.contract import vehicle_log

    path = Path(path)
    ulog = _open(path)
    topics = _topics(ulog)
    missing = [t for t in REQUIRED if t not in topics]
    acc_topic = "sensor_combined" if "sensor_combined" in topics else "vehicle_acceleration"
    if acc_topic not in topics:
        missing.append("sensor_combined or vehicle_acceleration")
    if missing:
        raise UserError(f"{path}: ULog without topic(s) {', '.join(missing)}")
    clock = topics["vehicle_local_position"].data["timestamp"] * 1e-6

    def field(topic: str, name: str) -> np.ndarray:
        d = topics[topic].data
        if name not in d:
            raise UserError(f"{path}: ULog topic {topic} has no field {name}")
        return np.interp(clock, d["timestamp"] * 1e-6, np.asarray(d[name], dtype=float), left=np.nan, right=np.nan)

    flip = np.array([1.0, -1.0, -1.0])  # NED/FRD -> z up (180 deg about x)
    lp = [field("vehicle_local_position", f) for f in TOPICS["vehicle_local_position"]]
    w, qx, qy, qz = (field("vehicle_attitude", f) for f in TOPICS["vehicle_attitude"])
    gyro = np.column_stack([field("vehicle_angular_velocity", f) for f in TOPICS["vehicle_angular_velocity"]]) * flip
    acc = np.column_stack([field(acc_topic, f) for f in TOPICS[acc_topic]]) * flip
    motors = [field("actuator_motors", f) for f in TOPICS["actuator_motors"]]
    fac = float(ulog.initial_parameters.get("THR_MDL_FAC", 0.0))
    columns = {"x": lp[0], "y": -lp[1], "z": -lp[2], "vx": lp[3], "vy": -lp[4], "vz": -lp[5],
               "qx": qx, "qy": -qy, "qz": -qz, "qw": w,
               "acc_x": acc[:, 0], "acc_y": acc[:, 1], "acc_z": acc[:, 2],
               "gyro_x": gyro[:, 0], "gyro_y": gyro[:, 1], "gyro_z": gyro[:, 2],
               "m1": motors[0], "m2": motors[1], "m3": motors[2], "m4": motors[3], "vbat": np.ones_like(clock)}  # fmt: skip
    return vehicle_log(clock, columns, source=str(path), thrust_shape=f"px4-thrust-model:{fac:g}", pwm_scale=1.0,
                       acc_scale=1.0, gyro_scale=1.0)  # fmt: skip


def describe_ulog(path: str | Path) -> dict[str, Any]:
    """Topics of a ULog with their rate and span, THR_MDL_FAC, and what is missing."""
    from proxplan.identify.formats.contract import stream_summary

    path = Path(path)
    ulog = _open(path)
    topics = _topics(ulog)
    streams = [stream_summary(name, d.data["timestamp"] * 1e-6, [k for k in d.data if k != "timestamp"])
               for name, d in topics.items()]  # fmt: skip
    missing = [t for t in REQUIRED if t not in topics]
    if "sensor_combined" not in topics and "vehicle_acceleration" not in topics:
        missing.append("sensor_combined or vehicle_acceleration")
    fac = ulog.initial_parameters.get("THR_MDL_FAC")
    mapping = {t: ", ".join(TOPICS[t]) for t in topics if t in TOPICS}
    thrust = f"from actuator_motors through PX4's thrust model (THR_MDL_FAC {fac if fac is not None else 'absent: 0'})"
    vehicle = {
        "name": path.name.split(".")[0],
        "streams": streams,
        "mapping": mapping,
        "missing": missing,
        "thrust": thrust,
    }
    return {"path": str(path), "format": "ulog", "truncated": False, "note": "", "vehicles": [vehicle]}
