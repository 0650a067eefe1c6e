"""Whole-process `proxplan plan` time for every shipped scenario, against a baseline measured in the
same run (the Python interpreter starting and importing the planner, i.e. the fixed cost).

Usage:  python benchmarks/bench_plan.py [--method sampling] [--repeat 3] [--no-plot]

Prints one line per scenario: median wall time of the whole process, planning time reported by the
plan, makespan, max authority usage, verify result, and the ratio of the wall time to the baseline.
Targets (issue 4): battery swap < 5 s, 8-vehicle swap < 30 s on the 2-core machine.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _wall(cmd: list[str]) -> tuple[float, subprocess.CompletedProcess]:
    t0 = time.perf_counter()
    res = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    return time.perf_counter() - t0, res


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--method", default="sampling", choices=("optimized", "sampling", "no-downwash", "ellipsoid"))
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--no-plot", action="store_true")
    args = ap.parse_args()
    baseline = statistics.median(
        _wall(
            [sys.executable, "-c", "import proxplan.planner.pipeline, proxplan.verify.checks, ompl.geometric, ruckig"]
        )[0]
        for _ in range(args.repeat)
    )
    print(f"baseline (interpreter + planner imports): {baseline:.2f} s")
    print(f"{'scenario':18s} {'wall_s':>7s} {'x base':>7s} {'plan_s':>7s} {'makespan_s':>10s} {'max_usage':>9s} verify")
    with tempfile.TemporaryDirectory() as tmp:
        for path in sorted((ROOT / "scenarios").glob("*.yaml")):
            walls, report = [], None
            for k in range(args.repeat):
                cmd = [
                    sys.executable,
                    "-m",
                    "proxplan.cli",
                    "plan",
                    str(path),
                    "--out",
                    f"{tmp}/{path.stem}{k}",
                    "--method",
                    args.method,
                    "--seed",
                    "0",
                    "--json",
                ] + (["--no-plot"] if args.no_plot else [])
                wall, res = _wall(cmd)
                walls.append(wall)
                report = json.loads(res.stdout) if res.stdout.strip() else {"feasible": False}
            if not report.get("feasible"):
                print(f"{path.stem:18s} infeasible: {report.get('vehicle')} / {report.get('constraint')}")
                continue
            m = report["metrics"]
            wall = statistics.median(walls)
            print(
                f"{path.stem:18s} {wall:7.2f} {wall / baseline:7.1f} {m['planning_time_s']:7.2f} "
                f"{m['makespan_s']:10.2f} {m['max_authority_usage']:9.3f} {'PASS' if report['verify']['passed'] else 'FAIL'}"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
