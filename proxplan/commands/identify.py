"""``proxplan identify MANIFEST.yaml --out DIR [--json] [--save-model FILE]`` (DESIGN.md section 6).

Module level imports only the standard library (fast ``proxplan --help``).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from pathlib import Path

from proxplan.fileio import atomic_write_text


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "identify",
        help="measure disturbances in flight logs, calibrate the model, find missing effects, report",
        description=(
            "Closing the loop with flight data: measure the disturbance on every vehicle (S0-11, S0-13), "
            "predict it with the model, calibrate c_ax, z0, c_rad, b_v and thrust scales on TRAIN flights, "
            "try each effect of the library and search for terms no library effect names; keep what flights held "
            "out confirm (grouped cross-validation by flight and stability selection); report on TEST flights. Writes DIR/report.md, "
            "DIR/identify.json and PNG plots. See docs/identify.md."
        ),
    )
    p.add_argument("manifest", help="manifest YAML (DESIGN.md section 6; root is relative to the manifest file)")
    p.add_argument("--out", required=True, help="output directory (created)")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.add_argument(
        "--save-model",
        metavar="FILE",
        help="write the calibrated model (vehicles, thrust scales, kept effects) for costmap/plan/simulate --model",
    )
    p.add_argument("--no-calibrate", action="store_true", help="skip the calibration stage (effects only)")
    p.add_argument("--derivative", choices=("savgol", "triangular", "difference"), default="savgol",
                   help="gyro derivative / smoothing: Savitzky-Golay (default), S0's triangular moving average, raw S0-12")  # fmt: skip
    p.add_argument("--window-s", type=float, default=0.15, help="smoothing window, s (default 0.15)")
    p.add_argument(
        "--motor-tau-s",
        type=float,
        default=None,
        help="motor time constant to compensate where logs hold commanded thrust, s "
        "(default: each vehicle type's motor_time_constant_s)",
    )
    p.add_argument(
        "--no-motor-lag",
        action="store_true",
        help="use the logged motor thrusts as delivered even where the manifest says they are commands",
    )
    p.add_argument("--workers", type=int, metavar="K", default=None,
                   help="processes (default: one per core; 1 runs every stage in this process; the pipeline has "
                        "two independent branches, so more than 2 act as 2); the result does not depend on it")  # fmt: skip
    p.set_defaults(func=run)


def calibrated_model(result):
    """The :class:`proxplan.physics.CalibratedModel` of an identify result (everything its "after" used:
    vehicles, options, effects, thrust scales, and how the disturbance was measured)."""
    return result.saved()


def model_yaml_dict(result) -> dict:
    """The model-file mapping (proxplan.physics.model_file format) of the calibrated model."""
    from proxplan.physics import model_file_dict

    return model_file_dict(calibrated_model(result))


def save_model(result, path: str | Path) -> Path:
    from proxplan.physics import write_model_file

    return write_model_file(calibrated_model(result), path)


def run(args: argparse.Namespace) -> int:
    from proxplan.fileio import UserError, check_output_file, output_folder
    from proxplan.identify import IdentifyOptions, MeasureOptions, load_manifest, run_identify, write_report

    if args.window_s <= 0 or (args.motor_tau_s is not None and args.motor_tau_s <= 0):
        raise UserError("--window-s and --motor-tau-s must be positive numbers of seconds")
    if args.workers is not None and args.workers < 1:
        raise UserError(f"--workers: expected a whole number >= 1, got {args.workers}")
    manifest = load_manifest(args.manifest)
    out = Path(args.out)
    if args.save_model:
        check_output_file(args.save_model, flag="--save-model")
    options = IdentifyOptions(
        measure=MeasureOptions(
            derivative=args.derivative,
            window_s=args.window_s,
            motor_time_constant_s=args.motor_tau_s,
            motor_lag=not args.no_motor_lag,
        ),
        calibrate=not args.no_calibrate,
        progress=True,
        workers=args.workers if args.workers is not None else os.cpu_count() or 1,
    )
    with output_folder(out) as stage:  # the report lands whole, or not at all
        result = run_identify(manifest, options=options)
        report = out / write_report(result, stage, manifest=str(args.manifest)).relative_to(stage)
        doc = result.to_json()
        doc["report"] = str(report)
        atomic_write_text(stage / "identify.json", json.dumps(doc, indent=2, default=float))
    if args.save_model:
        doc["saved_model"] = str(save_model(result, args.save_model))
    for warning in result.motor_lag_check.get("warnings", []):  # the measurement's self-check (motor lag)
        print(f"proxplan identify: warning: {warning}", file=sys.stderr)
    for line in result.undecided():  # too few flights to decide a term every held-out flight gained from
        print(f"proxplan identify: note: {line}", file=sys.stderr)
    for note in result.notes:  # e.g. logs without PWM/Vbat: the desired u[N] is used (said once)
        print(f"proxplan identify: note: {note}", file=sys.stderr)
    if result.fallback:  # too few flights to hold one out: what selection fell back to, in one line
        print(f"proxplan identify: note: {result.validation}", file=sys.stderr)
    if args.json:
        print(json.dumps(doc, default=float))
    else:
        b, a = result.before, result.after
        print(f"test RMSE F_z: {b.rmse_fz_N:.4g} N before -> {a.rmse_fz_N:.4g} N after; "
              f"torque {b.rmse_torque_Nm:.3g} -> {a.rmse_torque_Nm:.3g} N m")  # fmt: skip
        print(f"selected effects: {', '.join(result.selected) or 'none'}")
        if result.unexplained:
            print(f"unexplained residual correlates with {result.unexplained['feature']}")
        print(f"report: {report}", file=sys.stdout)
    return 0
