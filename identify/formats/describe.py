"""What a log holds (``proxplan logs``): vehicles, variables or topics, rate, duration, what maps to
what in the log contract, and what is missing; and a manifest skeleton that identify accepts."""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from proxplan.identify.formats.contract import CONTRACT, stream_summary, variable_table
from proxplan.identify.formats.registry import detect_format


def contract_mapping(available: set[str], overrides: Mapping[str, str] | None = None) -> tuple[dict, list[str]]:
    """Contract name -> log name found (or None), and the missing contract names."""
    table = variable_table(overrides, "variables")
    mapping = {k: (table[k] if table[k] in available else None) for k in CONTRACT}
    return mapping, [f"{k} ({table[k]})" for k, v in mapping.items() if v is None]


def describe_log(path: str | Path, *, topics: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Summary of one log file (see the module docstring); UserError when it is no log."""
    path = Path(path)
    fmt = detect_format(path)
    if fmt == "usdlog":
        from proxplan.identify.formats.usdlog import read_usdlog

        usd = read_usdlog(path)
        streams = [stream_summary(e.name, e.t_s, e.variables) for e in usd.events.values()]
        mapping, missing = contract_mapping({v for e in usd.events.values() for v in e.variables})
        vehicle = {"name": _vehicle_name(path), "streams": streams, "mapping": mapping, "missing": missing,
                   "thrust": "from PWM and battery voltage (no force in the log)"}  # fmt: skip
        return {"path": str(path), "format": f"usdlog v{usd.version}", "truncated": usd.truncated, "note": usd.note,
                "vehicles": [vehicle]}  # fmt: skip
    if fmt == "rosbag":
        from proxplan.identify.formats.rosbag import describe_bag

        return describe_bag(path, topics)
    if fmt == "ulog":
        from proxplan.identify.formats.ulog import describe_ulog

        return describe_ulog(path)
    from proxplan.identify.vehicle_log import read_log

    log = read_log(path)
    layout = "neural-swarm" if "time[ms]" in _header(path) else "canonical"
    vehicle = {"name": _vehicle_name(path), "streams": [stream_summary(layout, log.t_s, _header(path))],
               "mapping": {}, "missing": [],
               "thrust": "logged per-motor force" + (" with PWM and Vbat" if log.has_pwm else "")}  # fmt: skip
    return {"path": str(path), "format": layout, "truncated": False, "note": "", "vehicles": [vehicle]}


def _header(path: Path) -> list[str]:
    import gzip

    opener = gzip.open if path.suffix == ".gz" else open
    with opener(path, "rt") as fh:
        return [h.strip() for h in fh.readline().lstrip("#").split(",")]


def _vehicle_name(path: Path) -> str:
    """A vehicle name from a file name: its stem before a trailing _<run> (``cf51_00.usd`` -> cf51)."""
    stem = path.name.split(".")[0]
    return re.sub(r"_\d+$", "", stem) or stem


def manifest_skeleton(described: Sequence[dict[str, Any]], *, vehicle_type: str, root: Path) -> dict[str, Any]:
    """A manifest for the described logs: one flight per run number (``<vehicle>_<run>``; all logs in one
    flight without), the last flight ``test`` and the others ``train`` (a single flight: ``test``, which
    ``evaluate`` accepts; identify needs a train flight too)."""
    flights: dict[str, dict[str, Any]] = {}
    for d in described:
        path = Path(d["path"])
        run = re.search(r"_(\d+)$", path.name.split(".")[0])
        key = run.group(1) if run else "00"
        fl = flights.setdefault(key, {"name": f"flight_{key}", "split": "train", "vehicles": {}})
        for v in d["vehicles"]:
            entry: dict[str, Any] = {"type": vehicle_type, "log": _relative(path, root)}
            if v.get("topics"):
                entry["topics"] = v["topics"]
            fl["vehicles"][v["name"]] = entry
    ordered = [flights[k] for k in sorted(flights)]
    ordered[-1]["split"] = "test"
    formats = {d["format"].split()[0] for d in described}
    doc: dict[str, Any] = {"format": formats.pop() if len(formats) == 1 else "neural-swarm", "root": str(root)}
    if doc["format"] not in ("usdlog", "rosbag", "ulog", "neural-swarm", "canonical"):
        doc["format"] = "neural-swarm"
    doc["flights"] = ordered
    return doc


def _relative(path: Path, root: Path) -> str:
    try:
        return str(path.resolve().relative_to(root.resolve()))
    except ValueError:
        return str(path.resolve())
