"""Crazyflie uSD-card deck logs (the firmware's binary ``usdlog`` format, versions 1 and 2).

Written from the format's description (Bitcraze crazyflie-firmware, ``tools/usdlog/cfusdlog.py`` and
the uSD deck documentation). All integers little-endian:

* byte 0: magic 0xBC; then uint16 version (1 or 2) and uint16 number of event types;
* per event type: uint16 event id, its name (NUL-terminated; ``fixedFrequency`` for the periodic log
  of ``config.txt``), uint16 number of variables, and per variable ``name(t)`` NUL-terminated, ``t`` a
  Python ``struct`` type character (B H I b h i f e q Q d);
* records until the end: uint16 event id, a timestamp (version 1: uint32 milliseconds; version 2:
  uint64 microseconds), then the event's variables packed without padding;
* the last 4 bytes: CRC32 (zlib) of everything before them, written when logging stops.

A file cut short (the battery died in flight, no CRC written) is read up to its last whole record and
reported as truncated (:attr:`UsdLog.truncated`, :attr:`UsdLog.note`); that is no error. A file that
does not start with the magic byte, or whose header is cut, is a :class:`UserError`.
"""

from __future__ import annotations

import struct
import zlib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from proxplan.fileio import UserError, atomic_write_bytes

MAGIC = 0xBC
"""First byte of every uSD log."""
VERSIONS = (1, 2)
"""Format versions read: 1 (uint32 ms timestamps) and 2 (uint64 us timestamps)."""
TYPE_CHARS = "BHIbhifeqQd"
"""Variable type characters (Python ``struct``; the firmware writes B H I b h i f e)."""
_STAMP = {1: ("<HI", 1e-3), 2: ("<HQ", 1e-6)}  # record head and seconds per timestamp unit


@dataclass(frozen=True)
class UsdEvent:
    """One event type's records: timestamps (N,) s and each variable's values (N,)."""

    name: str
    event_id: int
    variables: tuple[str, ...]
    types: str  # one struct character per variable
    t_s: np.ndarray
    values: Mapping[str, np.ndarray]


@dataclass(frozen=True)
class UsdLog:
    """A decoded uSD log: its events by name, and whether the file was cut short."""

    path: str
    version: int
    events: Mapping[str, UsdEvent]
    truncated: bool = False
    note: str = ""  # why it counts as truncated (CRC missing / wrong, partial record at byte ...)
    unknown: dict = field(default_factory=dict)


def is_usdlog(head: bytes) -> bool:
    """True when ``head`` (the file's first bytes) starts like a uSD log (magic byte, version 1 or 2)."""
    return len(head) >= 3 and head[0] == MAGIC and struct.unpack_from("<H", head, 1)[0] in VERSIONS


def _name(data: bytes, idx: int, path: str) -> tuple[str, int]:
    end = data.find(b"\0", idx)
    if end < 0:
        raise UserError(f"{path}: uSD log header cut inside a name at byte {idx}; not a complete uSD log")
    try:
        return data[idx:end].decode("utf-8"), end + 1
    except UnicodeDecodeError:
        raise UserError(f"{path}: uSD log header has a name that is not text at byte {idx}") from None


def read_usdlog(path: str | Path) -> UsdLog:
    """Decode a uSD log file; UserError when it is no uSD log or its header is cut."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise UserError(f"{path}: log file not found") from None
    except OSError as err:
        raise UserError(f"{path}: cannot read log ({err})") from None
    where = str(path)
    if not is_usdlog(data[:3]):
        raise UserError(f"{path}: not a uSD log (expected magic byte 0xBC and version 1 or 2 at the start)")
    if len(data) < 5:
        raise UserError(f"{path}: uSD log header cut after {len(data)} bytes")
    version, n_types = struct.unpack_from("<HH", data, 1)
    idx = 5
    defs: dict[int, tuple[str, tuple[str, ...], str, struct.Struct]] = {}
    for _ in range(n_types):
        if idx + 2 > len(data):
            raise UserError(f"{path}: uSD log header cut after {len(data)} bytes (event definitions)")
        (event_id,) = struct.unpack_from("<H", data, idx)
        name, idx = _name(data, idx + 2, where)
        if idx + 2 > len(data):
            raise UserError(f"{path}: uSD log header cut in event {name!r}")
        (n_vars,) = struct.unpack_from("<H", data, idx)
        idx += 2
        names: list[str] = []
        types = ""
        for _ in range(n_vars):
            spec, idx = _name(data, idx, where)
            if len(spec) < 4 or spec[-3] != "(" or spec[-1] != ")" or spec[-2] not in TYPE_CHARS:
                raise UserError(
                    f"{path}: event {name!r}: variable {spec!r} is not 'name(t)' with t one of {TYPE_CHARS}"
                )
            names.append(spec[:-3])
            types += spec[-2]
        defs[event_id] = (name, tuple(names), types, struct.Struct("<" + types))
    crc_ok = len(data) - idx >= 4 and zlib.crc32(data[:-4]) == struct.unpack_from("<I", data, len(data) - 4)[0]
    end = len(data) - 4 if crc_ok else len(data)
    head = struct.Struct(_STAMP[version][0])
    rows: dict[int, list] = {k: [] for k in defs}
    stamps: dict[int, list] = {k: [] for k in defs}
    note = "" if crc_ok else "CRC32 missing or wrong (the file was cut: logging stopped without closing it)"
    while idx < end:
        if idx + head.size > end:
            note = note or f"partial record at byte {idx}"
            break
        event_id, stamp = head.unpack_from(data, idx)
        if event_id not in defs:
            note = (note + "; " if note else "") + f"unknown event id {event_id} at byte {idx}: read up to there"
            break
        body = defs[event_id][3]
        if idx + head.size + body.size > end:
            note = (note + "; " if note else "") + f"partial record at byte {idx}"
            break
        rows[event_id].append(body.unpack_from(data, idx + head.size))
        stamps[event_id].append(stamp)
        idx += head.size + body.size
    unit = _STAMP[version][1]
    events = {}
    for event_id, (name, var_names, var_types, _) in defs.items():
        table = np.array(rows[event_id], dtype=float).reshape(-1, len(var_names))
        events[name] = UsdEvent(name=name, event_id=event_id, variables=var_names, types=var_types,
                                t_s=np.asarray(stamps[event_id], dtype=float) * unit,
                                values={v: table[:, k] for k, v in enumerate(var_names)})  # fmt: skip
    return UsdLog(path=where, version=version, events=events, truncated=bool(note), note=note)


def usdlog_bytes(
    events: Mapping[str, tuple[np.ndarray, Mapping[str, tuple[str, np.ndarray]]]], *, version: int = 2
) -> bytes:
    """The bytes of a uSD log (with its CRC) holding ``events``: name -> (timestamps (N,) s,
    {variable: (type character, values (N,))}). Records of all events are written in time order.

    Written from the format description above (for tests, and for rewriting other logs in the
    firmware's format); timestamps are rounded to the version's unit (1 ms or 1 us).
    """
    if version not in VERSIONS:
        raise ValueError(f"version must be one of {VERSIONS}")
    fmt, unit = _STAMP[version]
    out = bytearray(struct.pack("<BHH", MAGIC, version, len(events)))
    recs: list[tuple[int, int, bytes]] = []
    for event_id, (name, (t_s, variables)) in enumerate(events.items()):
        out += struct.pack("<H", event_id) + name.encode() + b"\0" + struct.pack("<H", len(variables))
        types = "".join(t for t, _ in variables.values())
        for var, (t, _) in variables.items():
            out += f"{var}({t})".encode() + b"\0"
        body = struct.Struct("<" + types)
        ticks = np.round(np.asarray(t_s, dtype=float) / unit).astype(np.int64)
        cols = [np.asarray(v) for _, v in variables.values()]
        for k, tick in enumerate(ticks):
            vals = [float(c[k]) if t in "fed" else int(c[k]) for (t, _), c in zip(variables.values(), cols)]
            recs.append((int(tick), event_id, struct.pack(fmt, event_id, int(tick)) + body.pack(*vals)))
    for _, _, rec in sorted(recs, key=lambda r: (r[0], r[1])):
        out += rec
    return bytes(out) + struct.pack("<I", zlib.crc32(bytes(out)))


def write_usdlog(path: str | Path, events, *, version: int = 2) -> Path:
    """Write :func:`usdlog_bytes` to ``path`` atomically."""
    return atomic_write_bytes(Path(path), usdlog_bytes(events, version=version))
