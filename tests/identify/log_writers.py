"""Test-file writers: a PX4 ULog written from the format's published description (PX4 dev guide, "ULog
File Format"), a ROS 2 bag written by rosbags, and the synthetic two-vehicle flights they carry."""

from __future__ import annotations

import struct
from collections.abc import Mapping
from pathlib import Path

import numpy as np

ULOG_MAGIC = b"ULog\x01\x12\x35"


def _msg(kind: str, payload: bytes) -> bytes:
    return struct.pack("<HB", len(payload), ord(kind)) + payload


def write_ulog(
    path: Path, topics: Mapping[str, tuple[np.ndarray, Mapping[str, np.ndarray]]], params: Mapping[str, float]
) -> Path:
    """A ULog (version 1) holding ``topics``: name -> (timestamps (N,) us, {field: (N,) or (N, k) floats}),
    every field a float32 (array fields float[k]), plus float parameters ``params``.

    Layout (all little-endian): 16-byte header (magic, version, uint64 start time), a flag-bits message
    ('B', 40 bytes), one format message ('F': "name:uint64_t timestamp;float f;float[k] g;") per topic,
    parameters ('P': uint8 key length, "float NAME", float32), subscriptions ('A': uint8 multi id, uint16
    message id, name), then data messages ('D': uint16 message id, the packed fields) in time order."""
    out = bytearray(ULOG_MAGIC + bytes([1]) + struct.pack("<Q", 0))
    out += _msg("B", bytes(16) + struct.pack("<3Q", 0, 0, 0))
    for name, (_, fields) in topics.items():
        spec = "uint64_t timestamp;" + "".join(
            f"float[{np.shape(v)[1]}] {f};" if np.ndim(v) == 2 else f"float {f};" for f, v in fields.items()
        )
        out += _msg("F", f"{name}:{spec}".encode())
    for key, value in params.items():
        k = f"float {key}".encode()
        out += _msg("P", bytes([len(k)]) + k + struct.pack("<f", value))
    records = []
    for msg_id, (name, (stamps, fields)) in enumerate(topics.items()):
        out += _msg("A", struct.pack("<BH", 0, msg_id) + name.encode())
        cols = [np.asarray(v, dtype=np.float32).reshape(len(stamps), -1) for v in fields.values()]
        table = np.concatenate(cols, axis=1)
        for k, t in enumerate(stamps):
            records.append((int(t), msg_id, struct.pack("<HQ", msg_id, int(t)) + table[k].tobytes()))
    for _, _, rec in sorted(records, key=lambda r: (r[0], r[1])):
        out += _msg("D", rec)
    path.write_bytes(bytes(out))
    return path


def write_pose_log_bag(
    path: Path,
    vehicles: Mapping[str, tuple[np.ndarray, Mapping[str, np.ndarray]]],
    *,
    storage: str = "mcap",
    vars_: list[str],
) -> Path:
    """A ROS 2 bag (rosbags' own writer) with, per vehicle NAME, ``/NAME/pose`` (PoseStamped from the
    stateEstimate.x/y/z/qx..qw columns) and ``/NAME/log1`` (LogDataGeneric holding ``vars_`` in order)."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    from proxplan.identify.formats.rosbag import LOG_DATA_GENERIC, typestore

    store = typestore()
    T = store.types
    header, stamp = T["std_msgs/msg/Header"], T["builtin_interfaces/msg/Time"]
    pose_t, pose, point, quat = (T[k] for k in ("geometry_msgs/msg/PoseStamped", "geometry_msgs/msg/Pose",
                                               "geometry_msgs/msg/Point", "geometry_msgs/msg/Quaternion"))  # fmt: skip
    ldg = T[LOG_DATA_GENERIC]
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    with Writer(path, version=9, storage_plugin=plugin) as w:
        conns = {n: (w.add_connection(f"/{n}/pose", pose_t.__msgtype__, typestore=store),
                     w.add_connection(f"/{n}/log1", ldg.__msgtype__, typestore=store)) for n in vehicles}  # fmt: skip
        records = []
        for n, (t_s, cols) in vehicles.items():
            for k, t in enumerate(t_s):
                ns = int(round(t * 1e9))
                h = header(stamp=stamp(sec=ns // 10**9, nanosec=ns % 10**9), frame_id="world")
                c = {key: float(v[k]) for key, v in cols.items()}
                p = pose_t(header=h, pose=pose(
                    position=point(x=c["stateEstimate.x"], y=c["stateEstimate.y"], z=c["stateEstimate.z"]),
                    orientation=quat(x=c["stateEstimate.qx"], y=c["stateEstimate.qy"], z=c["stateEstimate.qz"],
                                     w=c["stateEstimate.qw"])))  # fmt: skip
                lg = ldg(
                    header=h, timestamp=np.uint32(ns // 10**6), values=np.array([c[v] for v in vars_], dtype=float)
                )
                records.append((ns, conns[n][0], store.serialize_cdr(p, pose_t.__msgtype__)))
                records.append((ns, conns[n][1], store.serialize_cdr(lg, ldg.__msgtype__)))
        for ns, conn, raw in sorted(records, key=lambda r: r[0]):
            w.write(conn, ns, raw)
    return path
