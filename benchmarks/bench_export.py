"""Crazyflie export: time and piece counts on the shipped scenarios and an N-vehicle formation change.

For every scenario: plan it (``--method sampling``, fresh process, timed), export every vehicle
(adaptive C2 7th-order fit, in process, timed), re-read the export and verify it. Prints per
scenario the vehicles, the export time and its ratio to the planning time measured in the same run,
pieces per vehicle (max / mean), the largest deviation from the plan, the verifier's verdict on the
exported folder, and as a baseline how many vehicles a plain fit on 31 equal pieces would have
kept within the tolerance and limits (and its time ratio to the adaptive fit).

Run: python benchmarks/bench_export.py [--formation 16] [--only battery_swap ...]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from proxplan.export import DEFAULT_TOLERANCE_M, export_crazyflie, vehicle_limits
from proxplan.export.polyfit import fit_ok, fit_uniform
from proxplan.planfile import CRAZYFLIE_MAX_PIECES, read_export, read_plan
from proxplan.verify import scenario_of_plan, verify_plan

REPO = Path(__file__).resolve().parents[1]


def _run(*args) -> None:
    res = subprocess.run([sys.executable, *map(str, args)], capture_output=True, text=True, cwd=REPO)
    if res.returncode != 0:
        raise SystemExit(f"failed: {' '.join(map(str, args))}\n{res.stderr}")


def bench(name: str, scenario: Path, work: Path) -> None:
    t = time.perf_counter()
    _run("-m", "proxplan.cli", "plan", scenario, "--out", work / name, "--method", "sampling", "--no-plot")
    plan_s = time.perf_counter() - t
    plan = read_plan(work / name)
    sc = scenario_of_plan(plan)
    t = time.perf_counter()
    summary = export_crazyflie(plan, sc, work / f"{name}_cf")
    export_s = time.perf_counter() - t
    pieces = [sum(f["pieces"] for f in v["files"]) for v in summary.values()]
    dev = max(f["max_deviation_m"] for v in summary.values() for f in v["files"])
    flown = read_export(work / f"{name}_cf")
    violations = verify_plan(flown, scenario_of_plan(flown))
    t = time.perf_counter()
    uniform_ok = sum(
        fit_ok(
            fit_uniform(tr, CRAZYFLIE_MAX_PIECES, vehicle_limits(plan, sc, n), DEFAULT_TOLERANCE_M), DEFAULT_TOLERANCE_M
        )
        for n, tr in plan.vehicles.items()
    )
    uniform_s = time.perf_counter() - t
    print(
        f"{name:22s} {len(plan.vehicles):3d} veh  export {export_s:6.2f} s = {export_s / plan_s:5.2f} x plan ({plan_s:5.1f} s)"
        f"  pieces max {max(pieces):2d} mean {np.mean(pieces):5.1f}  dev {1000 * dev:4.2f} mm"
        f"  verify {'PASS' if not violations else f'{len(violations)} violations'}"
        f"  | 31 equal pieces: {uniform_ok}/{len(plan.vehicles)} ok, {uniform_s / export_s:4.2f} x time"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--formation", type=int, default=16, help="vehicles of the generated formation change (0: none)")
    ap.add_argument("--only", nargs="*", help="shipped scenario stems to run (default: all)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        for path in sorted((REPO / "scenarios").glob("*.yaml")):
            if not args.only or path.stem in args.only:
                bench(path.stem, path, work)
        if args.formation:
            yaml_path = work / f"formation_{args.formation}.yaml"
            _run("-m", "proxplan.planner.formations", args.formation, "--out", yaml_path)
            bench(f"formation_{args.formation}", yaml_path, work)


if __name__ == "__main__":
    main()
