"""``proxplan export``: flyable files from a plan (argparse only at module level; heavy imports inside).

Exit codes: 0 written; 1 a vehicle does not fit the Crazyflie's 31 pieces within the tolerance
(nothing written; ``--split-time`` cuts it into several uploads); 2 user mistake.
"""

from __future__ import annotations

import argparse
import json
import sys

FORMATS = ("crazyflie", "csv")


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "export",
        help="write flyable files: Crazyflie polynomial CSVs or set-point CSVs with feed-forward",
        description=(
            "Export DIR/plan.json for flight. --format crazyflie: one uav_trajectories CSV per vehicle "
            "(Duration,x^0..x^7,y^0..y^7,z^0..z^7,yaw^0..yaw^7; C2 piecewise 7th-order polynomials, at most "
            "31 pieces, within --tolerance-m of the uploaded reference everywhere) and export.json, which "
            "`proxplan verify OUT` re-checks (the vehicles' predicted flight). By default the upload "
            "compensates rotor drag: it is the plan plus the lead the vehicle's gains and drag call for, "
            "with a settle tail after the plan's end, so the vehicle flies the plan (docs/flying.md). "
            "--format csv: NAME_setpoints.csv per vehicle (time, position, velocity, acceleration with the "
            "drag feed-forward, predicted downwash force/torque) at --rate-hz for PX4 offboard / ROS 2 "
            "streaming. Exit 1 when a vehicle needs more than 31 pieces (nothing written), 2 on bad input."
        ),
    )
    p.add_argument("plan", metavar="PLAN.json", help="plan file (or the folder holding plan.json)")
    p.add_argument("--format", required=True, choices=FORMATS, help="crazyflie (polynomials) or csv (set-points)")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder (created if missing)")
    p.add_argument(
        "--tolerance-m",
        type=float,
        default=None,
        metavar="M",
        help="crazyflie: largest allowed position deviation from the plan, m (default 0.002, a fifth of the 1 cm promised)",
    )
    p.add_argument(
        "--split-time",
        action="store_true",
        help="crazyflie: cut a vehicle that needs more than 31 pieces into consecutive uploads of <= 15 pieces",
    )
    p.add_argument("--rate-hz", type=float, default=None, metavar="HZ", help="csv: set-point rate, Hz (default 50)")
    p.add_argument(
        "--no-drag-compensation",
        action="store_true",
        help="upload / stream the plan itself: no rotor-drag lead (crazyflie) or drag feed-forward (csv)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import math
    from pathlib import Path

    from tqdm import tqdm

    from proxplan.export import (
        DEFAULT_RATE_HZ,
        DEFAULT_TOLERANCE_M,
        DoesNotFitError,
        export_crazyflie,
        export_setpoints,
    )
    from proxplan.fileio import UserError, output_folder
    from proxplan.planfile import read_plan
    from proxplan.verify import scenario_of_plan

    tolerance = DEFAULT_TOLERANCE_M if args.tolerance_m is None else args.tolerance_m
    rate = DEFAULT_RATE_HZ if args.rate_hz is None else args.rate_hz
    if not (math.isfinite(tolerance) and tolerance > 0):
        raise UserError(f"--tolerance-m: expected a positive distance in m, got {args.tolerance_m}")
    if not (math.isfinite(rate) and rate >= 2):
        raise UserError(f"--rate-hz: expected a rate of at least 2 Hz (PX4 offboard needs >= 2 Hz), got {args.rate_hz}")
    if args.format == "csv" and (args.tolerance_m is not None or args.split_time):
        raise UserError("--tolerance-m / --split-time: apply to --format crazyflie only")
    if args.format == "crazyflie" and args.rate_hz is not None:
        raise UserError("--rate-hz: applies to --format csv only")
    plan = read_plan(args.plan)
    has_scenario = plan.scenario_spec is not None or bool(plan.scenario_file)
    if args.format == "csv" or has_scenario:  # the feed-forward needs it; crazyflie uses its limits
        scenario = scenario_of_plan(plan, label=str(args.plan))
    else:
        scenario = None
    out = Path(args.out)
    notes: list[str] = []
    with output_folder(out) as stage:
        if args.format == "crazyflie":
            bar = tqdm(total=len(plan.vehicles), desc="export", unit="vehicle", file=sys.stderr, leave=False,
                       disable=not sys.stderr.isatty())  # fmt: skip
            try:
                vehicles = export_crazyflie(
                    plan,
                    scenario,
                    stage,
                    tolerance_m=tolerance,
                    split_time=args.split_time,
                    drag_compensation=not args.no_drag_compensation,
                    progress=lambda _: bar.update(),
                )
            except DoesNotFitError as err:
                bar.close()
                print(f"proxplan export: does not fit: {err}", file=sys.stderr)
                if args.json:
                    doc = {
                        "fits": False,
                        "vehicle": err.vehicle,
                        "pieces": err.pieces,
                        "max_deviation_m": err.deviation_m,
                        "tolerance_m": err.tolerance_m,
                        "kinematic_ratio": err.kinematic_ratio,
                        "message": str(err),
                    }
                    print(json.dumps(doc))
                return 1
            bar.close()
            files = [
                {
                    "vehicle": name,
                    **{k: f[k] for k in ("pieces", "max_deviation_m", "start_time_s", "duration_s")},
                    "file": str(out / f["file"]),
                    "drag_compensation": v["drag_compensation"],
                }
                for name, v in vehicles.items()
                for f in v["files"]
            ]
            if args.no_drag_compensation:
                notes.append(
                    "no drag compensation: the uploads are the plan; the vehicles will lag it by their rotor drag"
                )
            else:
                notes.append(
                    "rotor drag compensated: each upload is the plan + the lead its vehicle's gains and drag call for, "
                    "with a settle tail after the plan's end (proxplan verify checks the predicted flight)"
                )
            manifest: str | None = str(out / "export.json")
        else:
            assert scenario is not None
            rows, notes = export_setpoints(
                plan, scenario, stage, rate_hz=rate, drag_compensation=not args.no_drag_compensation
            )
            files = [
                {
                    "vehicle": name,
                    "file": str(out / r["file"]),
                    "pieces": None,
                    "rows": r["rows"],
                    "max_deviation_m": 0.0,
                    "max_drag_accel_mps2": r["max_drag_accel_mps2"],
                }
                for name, r in rows.items()
            ]
            manifest = None
    if args.json:
        print(
            json.dumps(
                {
                    "fits": True,
                    "format": args.format,
                    "out": str(out),
                    "manifest": manifest,
                    "drag_compensation": not args.no_drag_compensation,
                    "files": files,
                    "notes": notes,
                }
            )
        )
    else:
        for note in notes:
            print(f"note: {note}")
        for f in files:
            size = f"{f['pieces']} pieces" if f["pieces"] is not None else f"{f['rows']} rows"
            lead = f.get("drag_compensation")
            extra = ""
            if lead:
                extra = (
                    f"; leads the plan by up to {100 * lead['max_lead_m']:.1f} cm, "
                    f"settle tail {lead['tail_s']:.1f} s (lead left {1000 * lead['residual_m']:.1f} mm)"
                )
            elif "max_drag_accel_mps2" in f and not args.no_drag_compensation:
                extra = f"; drag feed-forward up to {f['max_drag_accel_mps2']:.2f} m/s^2"
            print(f"{f['file']}: {f['vehicle']}, {size}, max deviation {1000 * f['max_deviation_m']:.2f} mm{extra}")
        if manifest:
            print(f"wrote {manifest} (check the export with: proxplan verify {out})")
    return 0
