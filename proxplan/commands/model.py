"""`proxplan vehicles` and `proxplan wrench` (DESIGN.md section 4)."""

from __future__ import annotations

import argparse
import json
import math
import sys


def register(subparsers: argparse._SubParsersAction) -> None:
    vehicles = subparsers.add_parser(
        "vehicles",
        help="list vehicle types and their parameters",
        description="List the built-in vehicle types (and those of --vehicle-file) with every parameter and its unit.",
    )
    vehicles.add_argument("--vehicle-file", metavar="FILE.yaml", help="also list custom vehicles from this YAML file")
    vehicles.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    vehicles.set_defaults(func=run_vehicles)

    wrench = subparsers.add_parser(
        "wrench",
        help="disturbance wrench on a target below a hovering source",
        description=(
            "Force and torque on TARGET at OFFSET = p_target - p_source (world frame, z up, metres) "
            "in the downwash of a hovering SOURCE (seed 000 section II), with the target's "
            "controller-authority usage. Both vehicles hover level."
        ),
    )
    wrench.add_argument("--source", required=True, metavar="TYPE", help="vehicle type producing the downwash")
    wrench.add_argument("--target", required=True, metavar="TYPE", help="vehicle type receiving it")
    wrench.add_argument(
        "--offset", required=True, nargs=3, metavar=("DX", "DY", "DZ"),
        help="target position minus source position, m (DZ negative = target below)",
    )  # fmt: skip
    wrench.add_argument(
        "--field-form",
        default="inverse-z",
        choices=("inverse-z", "printed"),
        help="form of (S0-1): inverse-z (default, 1/z decay) or printed (1/sqrt(z))",
    )
    wrench.add_argument("--vehicle-file", metavar="FILE.yaml", help="custom vehicle types")
    wrench.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    wrench.set_defaults(func=run_wrench)


def _custom_vehicles(path: str | None) -> dict:
    if not path:
        return {}
    from proxplan.physics import load_vehicle_file

    return load_vehicle_file(path)


def run_vehicles(args: argparse.Namespace) -> int:
    from proxplan.physics import BUILTIN_VEHICLES

    vehicles = {**BUILTIN_VEHICLES, **_custom_vehicles(args.vehicle_file)}
    table = {name: v.to_dict() for name, v in vehicles.items()}
    if args.json:
        print(json.dumps({"vehicles": table}))
        return 0
    for name, d in table.items():
        p = d["propeller"]
        print(
            f"{name:18s} {d['mass_kg'] * 1000:7.1f} g  L={d['size_L_m'] * 1000:5.1f} mm  "
            f"prop {p['diameter_m'] * 1000:5.1f} mm  Tmax={d['max_thrust_N']:5.2f} N  "
            f"b_v={p['b_v_Nsm3prad2']:.3g} ({p['b_v_source']})  "
            f"c_ax={d['downwash']['c_ax']} z0={d['downwash']['z0_m']:.3f} m c_rad={d['downwash']['c_rad']}"
        )
        if d["description"]:
            print(f"{'':18s} {d['description']}")
    return 0


def _parse_offset(raw: list[str]) -> list[float]:
    from proxplan.fileio import UserError

    values = []
    for axis, text in zip("XYZ", raw):
        try:
            value = float(text)
        except ValueError:
            raise UserError(f"--offset D{axis}: expected a number in metres, got {text!r}") from None
        if not math.isfinite(value):
            raise UserError(f"--offset D{axis}: expected a finite number in metres, got {text!r}")
        values.append(value)
    return values


def run_wrench(args: argparse.Namespace) -> int:
    import numpy as np

    from proxplan.physics import ModelOptions, authority_usage, disturbance_wrench, resolve_vehicle

    offset = _parse_offset(args.offset)
    custom = _custom_vehicles(args.vehicle_file)
    source = resolve_vehicle(args.source, custom, where="--source")
    target = resolve_vehicle(args.target, custom, where="--target")
    batch = disturbance_wrench(source, target, np.array([offset]), ModelOptions(field_form=args.field_form))
    usage = float(authority_usage(target, batch.force_N, batch.torque_Nm)[0])
    result = {
        "force_N": batch.force_N[0].tolist(),
        "torque_Nm": batch.torque_Nm[0].tolist(),
        "components": {
            "drag": {"force_N": batch.drag_force_N[0].tolist(), "torque_Nm": batch.drag_torque_Nm[0].tolist()},
            "thrust_change": {
                "force_N": batch.thrust_force_N[0].tolist(),
                "torque_Nm": batch.thrust_torque_Nm[0].tolist(),
            },
        },
        "valid": bool(batch.valid[0]),
        "authority_usage": usage,
    }
    if args.json:
        print(json.dumps(result))
        return 0
    f, t = result["force_N"], result["torque_Nm"]
    print(f"{target.name} at offset {offset} m from hovering {source.name}:")
    print(
        f"  force   [N]   {f[0]:+.4f} {f[1]:+.4f} {f[2]:+.4f}  ({-f[2] / target.weight_N * 100:.1f} % of weight down)"
    )
    print(f"  torque  [N m] {t[0]:+.5f} {t[1]:+.5f} {t[2]:+.5f}")
    print(f"  drag Fz {batch.drag_force_N[0, 2]:+.4f} N, thrust change Fz {batch.thrust_force_N[0, 2]:+.4f} N")
    print(f"  authority usage {usage:.3f}")
    if not result["valid"]:
        print(
            f"  warning: dz = {-offset[2]:.3f} m is outside the zone of established flow "
            f"(dz > 3 L = {3 * source.size_m:.3f} m); the model is extrapolated here",
            file=sys.stderr,
        )
    return 0
