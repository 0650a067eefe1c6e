"""``proxplan evaluate MANIFEST --model MODEL.yaml [--split test|train|all] --out DIR [--json]``.

Score a saved model (``identify --save-model``) on flight logs without refitting. Module level
imports only the standard library (fast ``proxplan --help``).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def register(subparsers: argparse._SubParsersAction) -> None:
    p = subparsers.add_parser(
        "evaluate",
        help="score a saved model on flight logs without refitting (RMSE vs no model, per flight/vehicle/region)",
        description=(
            "Measure the disturbance on every scored vehicle of the manifest's flights exactly as the saved "
            "model's identify run did (delivered thrust from PWM and Vbat through the saved thrust maps), predict it "
            "with the saved model (calibrated vehicles, thrust scales, effects) and report the RMSE of F_z and "
            "torque against no model (zero disturbance). Vehicles with 'score: false' are downwash sources only. "
            "Writes DIR/evaluate.json, DIR/report.md and PNG plots. See docs/identify.md."
        ),
    )
    p.add_argument("manifest", help="manifest YAML (DESIGN.md section 6); all-test manifests are valid")
    p.add_argument("--model", required=True, metavar="MODEL.yaml", help="saved model (identify --save-model)")
    p.add_argument(
        "--split",
        choices=("test", "validation", "train", "all"),
        default="test",
        help="flights to score (default test)",
    )
    p.add_argument("--out", required=True, help="output directory (created)")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from proxplan.fileio import UserError, atomic_write_text, output_folder
    from proxplan.identify import evaluate_model, load_manifest, write_evaluation_report
    from proxplan.physics import load_model_file

    model = load_model_file(args.model)
    if model.format_version < 2:
        raise UserError(
            f"{args.model}: format_version: model format {model.format_version} holds no thrust scales or "
            "measurement settings, so its identify figures cannot be reproduced; re-run identify --save-model"
        )
    manifest = load_manifest(args.manifest, require_train_and_test=False)
    out = Path(args.out)
    with output_folder(out) as stage:
        result = evaluate_model(manifest, model, split=args.split, label=str(args.model), progress=True)
        report = write_evaluation_report(result, stage, manifest=str(args.manifest), model=str(args.model))
        doc = result.to_json()
        doc["report"] = str(out / report.relative_to(stage))
        atomic_write_text(stage / "evaluate.json", json.dumps(doc, indent=2, default=float))
    for warning in result.motor_lag_check.get("warnings", []):  # the measurement's self-check (motor lag)
        print(f"proxplan evaluate: warning: {warning}", file=sys.stderr)
    for note in result.notes:
        print(f"proxplan evaluate: note: {note}", file=sys.stderr)
    if args.json:
        print(json.dumps(doc, default=float))
    else:
        print(f"{args.split} RMSE F_z: {doc['rmse_fz_N']:.4g} N with the model, "
              f"{doc['no_model']['rmse_fz_N']:.4g} N without; {doc['n_samples']} of {doc['n_rows']} rows scored")  # fmt: skip
        print(f"report: {doc['report']}")
    return 0
