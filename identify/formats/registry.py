"""Which reader a log file needs, and reading one manifest vehicle entry into a :class:`VehicleLog`."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from proxplan.fileio import UserError
from proxplan.identify.flightlog import VehicleEntry
from proxplan.identify.vehicle_log import VehicleLog, read_log

LOG_FORMATS = ("neural-swarm", "canonical", "usdlog", "rosbag", "ulog")
"""Log formats a manifest may name (``format:``); CSV layouts are also told apart by their header,
binary ones by their first bytes (:func:`detect_format`)."""
BINARY_FORMATS = ("usdlog", "rosbag", "ulog")
ROSBAG_SUFFIXES = (".mcap", ".db3")
ULOG_MAGIC = b"ULog\x01\x12\x35"


def detect_format(path: str | Path) -> str:
    """``usdlog`` (magic byte 0xBC), ``ulog`` (``ULog`` magic), ``rosbag`` (a .mcap / .db3 file or a bag
    folder) or ``csv`` (anything else: the CSV reader tells its layout from the header)."""
    from proxplan.identify.formats.usdlog import is_usdlog

    path = Path(path)
    if path.is_dir() or path.suffix in ROSBAG_SUFFIXES:
        return "rosbag"
    try:
        with path.open("rb") as fh:
            head = fh.read(8)
    except FileNotFoundError:
        raise UserError(f"{path}: log file not found") from None
    except OSError as err:
        raise UserError(f"{path}: cannot read log ({err})") from None
    if head.startswith(ULOG_MAGIC):
        return "ulog"
    if is_usdlog(head):
        return "usdlog"
    return "csv"


def read_vehicle_log(entry: VehicleEntry, manifest_format: str = "") -> VehicleLog:
    """Read ``entry.log`` with the reader its content needs (the manifest's ``format`` must agree for
    binary formats), its clock shifted by ``entry.time_offset_s``."""
    found = detect_format(entry.log)
    if manifest_format in BINARY_FORMATS and found != manifest_format:
        what = "a CSV or unknown file" if found == "csv" else f"a {found} log"
        raise UserError(f"{entry.log}: the manifest says format: {manifest_format}, but the file is {what}")
    if found == "usdlog":
        from proxplan.identify.formats.firmware import log_from_streams
        from proxplan.identify.formats.usdlog import read_usdlog

        usd = read_usdlog(entry.log)
        streams = [(e.t_s, e.values) for e in usd.events.values() if len(e.t_s)]
        if not streams:
            raise UserError(f"{entry.log}: uSD log holds no records")
        log = log_from_streams(streams, source=str(entry.log), overrides=entry.variables)
    elif found == "rosbag":
        from proxplan.identify.formats.rosbag import read_bag_vehicle

        log = read_bag_vehicle(entry.log, entry.topics or {}, overrides=entry.variables)
    elif found == "ulog":
        from proxplan.identify.formats.ulog import read_ulog

        log = read_ulog(entry.log)
    else:
        log = read_log(entry.log)
    if entry.time_offset_s:
        log = replace(log, t_s=log.t_s + entry.time_offset_s)
    return log
