"""`proxplan track-limits`: measure a vehicle type's trackable kinematic limits and tracking tube
with the simulated controller (:mod:`proxplan.flightsim.tracking`, docs/flying.md).

    proxplan track-limits --vehicle crazyflie-2.1 [--vehicles FILE.yaml] [--budget 0.05]
                          [--out measured.yaml] [--json]

``--out`` writes a vehicle file holding the type with its measured ``kinematics`` and ``tracking``
(load it with ``proxplan plan --vehicles``).
"""

from __future__ import annotations

import argparse
import json
import shlex
import sys


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "track-limits",
        help="measure a vehicle type's trackable limits and tracking tube in closed-loop simulation",
        description=(
            "Fly the vehicle alone along a course of rest-to-rest jerk-limited segments at a ladder of "
            "speed / acceleration / jerk limits with the simulated controller, flying the drag-compensated "
            "reference the export uploads and measuring the error against the plan; keep the fastest level whose "
            "error quantile + margin stays within the budget (and within thrust-to-weight and tilt). Prints "
            "the limits, the tube and every flight; --out writes a vehicle file with them (docs/flying.md)."
        ),
    )
    p.add_argument("--vehicle", required=True, metavar="TYPE", help="vehicle type (built-in or from --vehicles)")
    p.add_argument("--vehicles", metavar="FILE.yaml", help="custom vehicle types (proxplan.physics.vehicle_yaml)")
    p.add_argument("--budget", type=float, default=None, metavar="M", help="largest tube accepted, m (default 0.02)")
    p.add_argument("--margin", type=float, default=None, metavar="M", help="margin over the error quantile, m (0.005)")
    p.add_argument("--quantile", type=float, default=None, metavar="Q", help="error quantile in (0, 1] (0.99)")
    p.add_argument("--controller", choices=("mellinger", "rotorpy"), default="mellinger", help="simulated controller")
    p.add_argument(
        "--no-drag-compensation",
        action="store_true",
        help="fly the plan itself instead of the drag-compensated reference the export uploads (docs/flying.md)",
    )
    p.add_argument("--out", metavar="FILE.yaml", help="write a vehicle file with the measured limits and tube")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.set_defaults(func=run_track_limits)


def _check(value: float | None, flag: str, lo: float, hi: float) -> None:
    from proxplan.fileio import UserError

    if value is not None and not (lo < value <= hi):
        raise UserError(f"{flag}: expected a number in ({lo:g}, {hi:g}], got {value:g}")


def run_track_limits(args: argparse.Namespace) -> int:
    from proxplan.fileio import UserError, atomic_write_text
    from proxplan.flightsim import ERROR_QUANTILE, measure_tracking
    from proxplan.physics import (
        BUILTIN_VEHICLES,
        TUBE_BUDGET_M,
        TUBE_MARGIN_M,
        load_vehicle_file,
        resolve_vehicle,
        vehicle_to_yaml_dict,
    )

    _check(args.budget, "--budget", 0.0, 1.0)
    _check(args.margin, "--margin", -1e-12, 0.5)
    _check(args.quantile, "--quantile", 0.0, 1.0)
    custom = load_vehicle_file(args.vehicles) if args.vehicles else None
    vehicle = resolve_vehicle(args.vehicle, custom, where="--vehicle")
    budget = args.budget if args.budget is not None else TUBE_BUDGET_M
    margin = args.margin if args.margin is not None else TUBE_MARGIN_M
    quantile = args.quantile if args.quantile is not None else ERROR_QUANTILE
    words = ["proxplan", "track-limits", "--vehicle", args.vehicle]
    words += ["--vehicles", args.vehicles] if args.vehicles else []
    words += ["--budget", f"{budget:g}", "--margin", f"{margin:g}", "--quantile", f"{quantile:g}"]
    words += ["--controller", args.controller] + (["--no-drag-compensation"] if args.no_drag_compensation else [])
    command = " ".join(shlex.quote(w) for w in words)
    try:
        result = measure_tracking(
            vehicle,
            budget_m=budget,
            margin_m=margin,
            quantile=quantile,
            controller=args.controller,
            command=command,
            progress=sys.stderr.isatty(),
            drag_compensation=not args.no_drag_compensation,
        )
    except ValueError as err:
        raise UserError(str(err)) from None
    out = result.to_dict()
    if args.out:
        import yaml

        base = vehicle.name if vehicle.name in BUILTIN_VEHICLES and custom is None else None
        doc = {"vehicles": {vehicle.name: vehicle_to_yaml_dict(result.vehicle, base=base)}}
        atomic_write_text(args.out, yaml.safe_dump(doc, sort_keys=False))
        out["out"] = str(args.out)
    if args.json:
        print(json.dumps(out))
    else:
        k, t = out["kinematic_limits"], out["tracking"]
        print(
            f"{vehicle.name}: {k['max_speed_mps']:g} m/s, {k['max_accel_mps2']:g} m/s^2, {k['max_jerk_mps3']:g} m/s^3; "
            f"tube {t['tube_m'] * 100:.1f} cm (error q{t['error_quantile']:g} {t['quantile_error_m'] * 100:.1f} cm "
            f"+ margin {t['margin_m'] * 100:.1f} cm, max {t['max_error_m'] * 100:.1f} cm); limited by {t['limited_by']}"
        )
    return 0
