"""ROS 2 bags (``.mcap``, sqlite3 ``.db3``, or a bag folder) through ``rosbags``.

One vehicle's topics (the manifest's ``topics:``, Crazyswarm2 names ``/cfN/...``):

* ``pose`` — ``geometry_msgs/msg/PoseStamped``: position (m, world) and orientation (body -> world)
  fill the contract's x, y, z, qx..qw (the onboard estimate Crazyswarm2 publishes as ``/cfN/pose``);
* ``imu`` — ``sensor_msgs/msg/Imu``: ``linear_acceleration`` (m/s^2, body frame, specific force:
  divided by 9.80665 into the firmware's g) and ``angular_velocity`` (rad/s, body: into deg/s), so
  they enter the contract like the firmware's acc.* and gyro.*;
* ``log`` — Crazyswarm2's ``crazyflie_interfaces/msg/LogDataGeneric`` topics: ``values`` in the order
  of the ``vars`` of the robot's logging config (``firmware_logging.custom_topics.NAME.vars`` in
  crazyflies.yaml), which the manifest repeats (``{topic, vars}``); firmware names and units.

Every message is stamped with its header's time (the bag's clock: ROS time at the host), so the
vehicles of one bag share one clock; a message whose header stamp is 0 takes the bag's receive time.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from proxplan.fileio import UserError
from proxplan.identify.formats.contract import DEG, G0_MPS2
from proxplan.identify.vehicle_log import VehicleLog

LOG_DATA_GENERIC = "crazyflie_interfaces/msg/LogDataGeneric"
LOG_DATA_GENERIC_MSG = (
    "std_msgs/Header header  # Header including the ROS2 timestamp when the log data was received\n"
    "uint32 timestamp        # on-board timestamp from the STM32 (in ms)\n"
    "float64[] values        # converted values, in the order as specified for the log block\n"
)
"""Crazyswarm2's message definition (crazyflie_interfaces), registered with the ROS 2 Humble types."""
POSE, IMU = "geometry_msgs/msg/PoseStamped", "sensor_msgs/msg/Imu"


def typestore():
    """ROS 2 Humble's message types plus Crazyswarm2's LogDataGeneric (rosbags typestore)."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    store.register(get_types_from_msg(LOG_DATA_GENERIC_MSG, LOG_DATA_GENERIC))
    return store


def _reader(path: Path):
    from rosbags.rosbag2 import Reader

    try:
        reader = Reader(path)
        reader.open()
    except FileNotFoundError:
        raise UserError(f"{path}: log file not found") from None
    except Exception as err:  # rosbags raises its own errors (and sqlite3's) on a file that is no bag
        raise UserError(
            f"{path}: not a readable ROS 2 bag ({str(err).splitlines()[0] if str(err) else type(err).__name__})"
        ) from None
    return reader


def _stamp_s(msg: Any, receive_ns: int) -> float:
    st = msg.header.stamp
    ns = int(st.sec) * 1_000_000_000 + int(st.nanosec)
    return (ns if ns else receive_ns) * 1e-9


def read_topics(path: str | Path, topics: Mapping[str, Any]) -> list[tuple[np.ndarray, dict[str, np.ndarray]]]:
    """The named topics of ``path`` as streams (timestamps (N,) s, {firmware name: values (N,)})."""
    path = Path(path)
    wanted: dict[str, tuple[str, Any]] = {}
    if topics.get("pose"):
        wanted[topics["pose"]] = ("pose", None)
    if topics.get("imu"):
        wanted[topics["imu"]] = ("imu", None)
    for item in topics.get("log") or ():
        wanted[item["topic"]] = ("log", list(item["vars"]))
    if not wanted:
        raise UserError(f"{path}: topics: name at least one of pose, imu, log for this vehicle (manifest 'topics:')")
    store = typestore()
    rows: dict[str, list] = {t: [] for t in wanted}
    stamps: dict[str, list] = {t: [] for t in wanted}
    reader = _reader(path)
    try:
        present = {c.topic: c for c in reader.connections}
        for topic in wanted:
            if topic not in present:
                raise UserError(
                    f"{path}: topic {topic} not in the bag (topics: {', '.join(sorted(present)) or 'none'})"
                )
        conns = [present[t] for t in wanted]
        for conn, receive_ns, raw in reader.messages(connections=conns):
            kind, names = wanted[conn.topic]
            msg = store.deserialize_cdr(raw, conn.msgtype)
            stamps[conn.topic].append(_stamp_s(msg, receive_ns))
            if kind == "pose":
                p, q = msg.pose.position, msg.pose.orientation
                rows[conn.topic].append((p.x, p.y, p.z, q.x, q.y, q.z, q.w))
            elif kind == "imu":
                a, w = msg.linear_acceleration, msg.angular_velocity
                rows[conn.topic].append((a.x / G0_MPS2, a.y / G0_MPS2, a.z / G0_MPS2, w.x / DEG, w.y / DEG, w.z / DEG))
            else:
                vals = np.asarray(msg.values, dtype=float)
                if vals.size != len(names):
                    raise UserError(f"{path}: topic {conn.topic}: a message holds {vals.size} values, the manifest "
                                    f"names {len(names)} vars")  # fmt: skip
                rows[conn.topic].append(tuple(vals))
    finally:
        reader.close()
    streams = []
    for topic, (kind, names) in wanted.items():
        if kind == "pose":
            names = ["stateEstimate.x", "stateEstimate.y", "stateEstimate.z",
                     "stateEstimate.qx", "stateEstimate.qy", "stateEstimate.qz", "stateEstimate.qw"]  # fmt: skip
        elif kind == "imu":
            names = ["acc.x", "acc.y", "acc.z", "gyro.x", "gyro.y", "gyro.z"]
        table = np.asarray(rows[topic], dtype=float).reshape(-1, len(names))
        t = np.asarray(stamps[topic], dtype=float)
        order = np.argsort(t, kind="stable")
        streams.append((t[order], {n: table[order, k] for k, n in enumerate(names)}))
    return streams


def read_bag_vehicle(
    path: str | Path, topics: Mapping[str, Any], *, overrides: Mapping[str, str] | None = None
) -> VehicleLog:
    """One vehicle of a bag as a :class:`VehicleLog` (its ``topics``; module docstring)."""
    from proxplan.identify.formats.firmware import log_from_streams

    streams = [s for s in read_topics(path, topics) if len(s[0])]
    if not streams:
        raise UserError(f"{path}: the vehicle's topics hold no messages")
    return log_from_streams(streams, source=str(path), overrides=overrides, what="variable")


def describe_bag(path: str | Path, topics: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Topics of a bag grouped by vehicle namespace (``/cfN/...``) with type, count, rate and span."""
    from proxplan.identify.formats.contract import stream_summary

    path = Path(path)
    reader = _reader(path)
    try:
        conns = list(reader.connections)
        times: dict[str, list[int]] = {c.topic: [] for c in conns}
        for conn, ns, _ in reader.messages(connections=conns):
            times[conn.topic].append(ns)
    finally:
        reader.close()
    vehicles: dict[str, dict[str, Any]] = {}
    for c in conns:
        ns = c.topic.strip("/").split("/")[0] if c.topic.count("/") > 1 else "bag"
        v = vehicles.setdefault(ns, {"name": ns, "streams": [], "mapping": {}, "missing": [],
                                     "thrust": "from PWM and battery voltage (motor.m1..m4, pm.vbat in a log topic)",
                                     "topics": {}})  # fmt: skip
        s = stream_summary(c.topic, np.asarray(times[c.topic], dtype=float) * 1e-9, [c.msgtype])
        v["streams"].append(s)
        if c.msgtype == POSE:
            v["topics"]["pose"] = c.topic
        elif c.msgtype == IMU:
            v["topics"]["imu"] = c.topic
        elif c.msgtype == LOG_DATA_GENERIC:
            v["topics"].setdefault("log", []).append({"topic": c.topic, "vars": ["<the logging config's vars>"]})
    for v in vehicles.values():
        have = set()
        if "pose" in v["topics"]:
            have |= {"x", "y", "z", "qx", "qy", "qz", "qw"}
        if "imu" in v["topics"]:
            have |= {"acc_x", "acc_y", "acc_z", "gyro_x", "gyro_y", "gyro_z"}
        v["mapping"] = {k: ("pose" if k in {"x", "y", "z", "qx", "qy", "qz", "qw"} else "imu") for k in sorted(have)}
        v["missing"] = [k + " (a LogDataGeneric topic's vars must hold it)" for k in
                        ("vx", "vy", "vz", "m1", "m2", "m3", "m4", "vbat") if k not in have]  # fmt: skip
    return {"path": str(path), "format": "rosbag", "truncated": False, "note": "", "vehicles": list(vehicles.values())}
