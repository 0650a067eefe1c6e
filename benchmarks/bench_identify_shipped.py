"""Speed of ``proxplan identify`` on every shipped Neural-Swarm set (issue 24: < 120 s on this machine).

Runs the whole pipeline (load, checks, thrust maps, measurement with motor lag, calibration, stack
shielding, effect search, discovery over the widened dictionary, before/after errors) on
``manifests/neural-swarm.yaml`` (train + validation + test flights of all seven swap sets and the
take-offs; the logs are read from ``../shared``), then ``evaluate`` of the saved model on the test
flights. Baseline measured in the same run: loading and measuring every flight alone
(:func:`proxplan.identify.loading.load_units`), reported as a ratio.

    python benchmarks/bench_identify_shipped.py [--manifest manifests/neural-swarm.yaml] [--json]
"""

from __future__ import annotations

import argparse
import json
import resource
import time
from pathlib import Path

from proxplan.identify import IdentifyOptions, evaluate_model, load_manifest, run_identify
from proxplan.identify.loading import load_units

ROOT = Path(__file__).resolve().parents[1]
BUDGET_S = 120.0


def _timed(fn):
    w0, c0 = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - w0, time.process_time() - c0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--manifest", default=str(ROOT / "manifests" / "neural-swarm.yaml"))
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = ap.parse_args()
    manifest = load_manifest(args.manifest)
    _, base_wall, base_cpu = _timed(lambda: load_units(manifest, options=IdentifyOptions()))
    result, wall, cpu = _timed(lambda: run_identify(manifest, options=IdentifyOptions()))
    model = result.saved()
    ev, ev_wall, ev_cpu = _timed(lambda: evaluate_model(manifest, model))
    doc = ev.to_json()
    out = {
        "flights": len(manifest.flights),
        "identify_wall_s": wall, "identify_cpu_s": cpu, "budget_s": BUDGET_S, "within_budget": wall < BUDGET_S,
        "load_and_measure_wall_s": base_wall, "identify_over_load_and_measure": wall / base_wall,
        "evaluate_wall_s": ev_wall, "evaluate_cpu_s": ev_cpu,
        "peak_rss_MB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
        "test_ratio_fz": doc["rmse_fz_N"] / doc["no_model"]["rmse_fz_N"],
        "sets": {k: v["ratio_fz"] for k, v in doc["sets"].items()},
        "overhead": {k: v["ratio_fz"] for k, v in doc["overhead"].items()},
        "stack_shielding": result.stack_shielding,
    }  # fmt: skip
    if args.json:
        print(json.dumps(out, indent=2))
        return
    print(f"identify on {out['flights']} flights: {wall:.1f} s wall, {cpu:.1f} s CPU (budget {BUDGET_S:.0f} s: "
          f"{'ok' if out['within_budget'] else 'OVER'}); load+measure alone {base_wall:.1f} s -> ratio "
          f"{out['identify_over_load_and_measure']:.1f}x")  # fmt: skip
    print(f"evaluate (test flights): {ev_wall:.1f} s wall; peak RSS {out['peak_rss_MB']:.0f} MB")
    print(f"test F_z RMSE / no model: pooled {out['test_ratio_fz']:.3f}")
    for k, v in out["sets"].items():
        print(f"  {k:12s} {v:.3f}" if v is not None else f"  {k:12s} n/a")
    print("  by sources overhead: " + ", ".join(f"{k}: {v:.3f}" for k, v in out["overhead"].items() if v is not None))


if __name__ == "__main__":
    main()
