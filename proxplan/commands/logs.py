"""``proxplan logs LOG... [--json] [--manifest OUT.yaml] [--type TYPE]``: what flight logs hold.

Module level imports only the standard library (fast ``proxplan --help``).
"""

from __future__ import annotations

import argparse
import json
import os
from pathlib import Path


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "logs",
        help="what flight logs hold (vehicles, variables/topics, rate, duration, contract mapping, what is missing)",
        description=(
            "Read each log (Crazyflie uSD, ROS 2 bag .mcap/sqlite3, PX4 ULog, Neural-Swarm or canonical CSV) and "
            "say what it holds: vehicles, variables or topics with their rate and duration, which of them fill the "
            "log contract of identify, what is missing, and whether a uSD log was cut short. With --manifest, write "
            "a manifest identify/evaluate accept (schema line included; one flight per run number <vehicle>_<NN>, "
            "the last one test). See docs/identify.md."
        ),
    )
    p.add_argument("logs", nargs="+", metavar="LOG", help="log files (or ROS 2 bag folders)")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument("--manifest", metavar="OUT.yaml", help="write a manifest for these logs")
    p.add_argument(
        "--type", default="crazyflie-2.1", help="vehicle type written into the manifest (default crazyflie-2.1)"
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import yaml

    from proxplan.fileio import atomic_write_text, check_output_file
    from proxplan.identify import describe_log, manifest_skeleton

    described = [describe_log(p) for p in args.logs]
    doc: dict = {"logs": described}
    if args.manifest:
        out = check_output_file(args.manifest, flag="--manifest")
        root = Path(os.path.commonpath([str(Path(d["path"]).resolve().parent) for d in described]))
        manifest = manifest_skeleton(described, vehicle_type=args.type, root=root)
        manifest["root"] = os.path.relpath(root, Path(out).resolve().parent)
        schema = os.path.relpath(
            Path(__file__).resolve().parents[2] / "schemas" / "manifest.json", Path(out).resolve().parent
        )
        text = (f"# yaml-language-server: $schema={schema}\n"
                f"# written by proxplan logs; check each vehicle's type and the flights' splits\n"
                + yaml.safe_dump(manifest, sort_keys=False))  # fmt: skip
        atomic_write_text(Path(out), text)
        doc["manifest"] = str(out)
    if args.json:
        print(json.dumps(doc, default=float))
        return 0
    for d in described:
        print(f"{d['path']}: {d['format']}" + (f" (TRUNCATED: {d['note']})" if d["truncated"] else ""))
        for v in d["vehicles"]:
            print(f"  vehicle {v['name']}: thrust {v['thrust']}")
            for s in v["streams"]:
                rate = f"{s['rate_hz']:.1f} Hz" if s["rate_hz"] else "-"
                print(
                    f"    {s['name']}: {s['samples']} samples, {rate}, {s['duration_s']:.2f} s: {', '.join(s['variables'])}"
                )
            mapped = [f"{k}<-{n}" for k, n in v["mapping"].items() if n]
            if mapped:
                print(f"    contract: {', '.join(mapped)}")
            if v["missing"]:
                print(f"    missing: {', '.join(v['missing'])}")
    if args.manifest:
        print(f"wrote {doc['manifest']}")
    return 0
