"""The shipped Neural-Swarm flights rewritten as Crazyflie uSD logs, identified and evaluated end to end.

    python scripts/usdlog_neural_swarm.py [--manifest manifests/neural-swarm.yaml] [--flights REGEX]
                                          [--no-csv] [--keep DIR] [--json FILE]

Every log of the manifest is rewritten as the firmware's binary uSD log (``usdlog`` version 2, event
``fixedFrequency``) with the firmware's variable names and units (stateEstimate.*, acc.* in g in the
body frame, gyro.* in deg/s, motor.m1..m4 in PWM counts, pm.vbat) and WITHOUT the desired forces
u1..u4[N] (no stock firmware logs them), into a temporary folder (never into the repository; ``--keep``
keeps it). A manifest with ``format: usdlog`` and the same flights, splits and vehicles is identified
(thrust from PWM and Vbat: the published Foerster map for crazyflie-2.1, a free-flight scale for the
Parrot-frame crazyflie-parrot) and its saved model evaluated on the test flights. The same is done on
the CSV logs (logged forces) for comparison unless ``--no-csv``.

Printed: the pooled test RMSE of F_z in grams and its ratio to no model on the two-vehicle swaps
(swap_sl, swap_ss, swap_ll test flights: the shipped manifest's test flights stand in for "held-out"
flights; they never fit or choose anything), per day, and each vehicle's thrust source.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
import tempfile
from pathlib import Path

import numpy as np
import yaml

REPO = Path(__file__).resolve().parents[1]
TWO_VEHICLE_SETS = ("swap_sl", "swap_ss", "swap_ll")
"""The two-vehicle swap sets of the Neural-Swarm data (shared README)."""


def rewrite_as_usd(manifest_path: Path, out: Path, flights: str) -> Path:
    """Write every log of ``manifest_path`` (flights matching ``flights``) as a uSD log under ``out``
    and a ``format: usdlog`` manifest beside them; returns the manifest path."""
    from proxplan.identify import firmware_columns, load_manifest, read_log, write_usdlog

    manifest = load_manifest(manifest_path)
    entries = []
    for fl in manifest.flights:
        if not re.search(flights, fl.name):
            continue
        vehicles = {}
        for v in fl.vehicles:
            rel = Path(v.log).relative_to(manifest.root)
            usd = out / rel.parent / (rel.name.split(".")[0] + ".usd")
            log = read_log(v.log)
            write_usdlog(usd, {"fixedFrequency": (log.t_s, firmware_columns(log))})
            entry = {"type": v.type, "log": str(usd.relative_to(out)), "ground_z_m": v.ground_z_m}
            if not v.score:
                entry["score"] = False
            vehicles[v.name] = entry
        entries.append({"name": fl.name, "split": fl.split, "set": fl.set, "vehicles": vehicles})
    path = out / "manifest.yaml"
    path.write_text(yaml.safe_dump({"format": "usdlog", "root": ".", "flights": entries}, sort_keys=False))
    return path


def _pooled(parts: list[dict]) -> dict:
    n = sum(p["n_samples"] for p in parts)
    if not n:
        return {"n_samples": 0}
    sse = sum(p["n_samples"] * p["rmse_fz_N"] ** 2 for p in parts)
    sse0 = sum(p["n_samples"] * p["no_model_rmse_fz_N"] ** 2 for p in parts)
    g = 1000.0 / 9.80665
    return {"n_samples": n, "rmse_fz_g": g * float(np.sqrt(sse / n)), "no_model_rmse_fz_g": g * float(np.sqrt(sse0 / n)),
            "ratio_fz": float(np.sqrt(sse / sse0))}  # fmt: skip


def identify_and_evaluate(manifest_path: Path, flights: str) -> dict:
    """identify (train/validation flights) then evaluate its saved model on the test flights."""
    from proxplan.identify import evaluate_model, load_manifest, run_identify, saved_model

    manifest = load_manifest(manifest_path)
    if flights != ".*":
        from dataclasses import replace

        manifest = replace(manifest, flights=tuple(f for f in manifest.flights if re.search(flights, f.name)))
    result = run_identify(manifest, thrust_summary=False)
    model = saved_model(result.final_model, result.measure_options, result.thrust_maps)
    ev = evaluate_model(manifest, model, split="test").to_json()
    sets = ev["sets"]
    day23 = [s for k, s in sets.items() if k.startswith("day23")]
    day21 = [s for k, s in sets.items() if not k.startswith("day23")]
    return {
        "two_vehicle_swaps": _pooled([sets[k] for k in TWO_VEHICLE_SETS if k in sets]),
        "day21": _pooled(day21),
        "day23": _pooled(day23),
        "all_test": {
            "rmse_fz_g": ev["rmse_fz_g"],
            "no_model_rmse_fz_g": ev["no_model"]["rmse_fz_g"],
            "ratio_fz": ev["ratio_fz"],
            "n_samples": ev["n_samples"],
        },  # fmt: skip
        "sets": {
            k: {"rmse_fz_g": v["rmse_fz_g"], "ratio_fz": v["ratio_fz"], "n_samples": v["n_samples"]}
            for k, v in sets.items()
        },  # fmt: skip
        "identify_after_rmse_fz_N": result.after.rmse_fz_N,
        "selected": list(result.selected),
        "thrust_source": {name: d["thrust_source"] for name, d in ev["measurement"]["saturation"].items()},
        "thrust_maps": {t: {"source": m.source, "coef": list(m.coef)} for t, m in result.thrust_maps.items()},
        "thrust_scale": dict(result.final_model.thrust_scale),
        "notes": list(ev["notes"]),
        "warnings": list(ev["warnings"]),
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--manifest", type=Path, default=REPO / "manifests" / "neural-swarm.yaml")
    ap.add_argument("--flights", default=".*", help="only flights whose name matches this regex (quick runs)")
    ap.add_argument("--no-csv", action="store_true", help="skip the CSV (logged-force) comparison run")
    ap.add_argument("--keep", type=Path, help="keep the uSD logs and their manifest in this folder")
    ap.add_argument("--json", type=Path, help="write the figures as JSON here")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="usd-neural-swarm-") as tmp:
        out = args.keep or Path(tmp)
        usd_manifest = rewrite_as_usd(args.manifest, out, args.flights)
        print(f"rewrote the logs as uSD files under {out}", file=sys.stderr)
        figures = {"usdlog": identify_and_evaluate(usd_manifest, args.flights)}
    if not args.no_csv:
        figures["csv"] = identify_and_evaluate(args.manifest, args.flights)
    for path, fig in figures.items():
        p = fig["two_vehicle_swaps"]
        if p["n_samples"]:
            print(f"{path}: two-vehicle swaps (test): {p['rmse_fz_g']:.2f} g, {p['ratio_fz']:.3f} of no model "
                  f"({p['no_model_rmse_fz_g']:.2f} g), {p['n_samples']} samples")  # fmt: skip
        for day in ("day21", "day23"):
            d = fig[day]
            if d["n_samples"]:
                print(
                    f"{path}: {day} test: {d['rmse_fz_g']:.2f} g, {d['ratio_fz']:.3f} of no model ({d['n_samples']} samples)"
                )
        print(
            f"{path}: thrust sources {fig['thrust_source']}; maps {[(t, m['source']) for t, m in fig['thrust_maps'].items()]}"
        )
    text = json.dumps(figures, indent=2, default=float)
    if args.json:
        args.json.write_text(text)
    else:
        print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
