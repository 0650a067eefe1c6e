"""Swarm benchmark (issue 14): formation changes of N vehicles planned by `proxplan plan`.

Usage:  python benchmarks/bench_swarm.py [--n 8 16 32 64 128] [--optimized] [--timeout 600]

For every N a formation-change scenario is generated (``proxplan.planner.formations``: two staggered layers
0.5 m apart west of a pillar, every vehicle flies to the other layer on the east side, mixed
Crazyflie / Crazyflie-Parrot / small-quad). Each plan runs in its own subprocess and the script
prints: whole-process wall time (s, and as a ratio to the interpreter + planner-import baseline
measured in the same run), makespan / lower bound (lower bound = the largest single-vehicle
straight-line rest-to-rest minimum time under its own speed / acceleration / jerk limits,
``proxplan.planner.ordering.lower_bound_makespan_s``), peak memory of the child (``resource`` rusage of the
waited child, MB), the verdict of ``proxplan verify`` on the written plan.json, and with
``--optimized`` the same for ``--method optimized``.

Targets on the 2-core machine: 64 vehicles sampling < 30 s and makespan <= 1.6 x lower bound;
128 vehicles < 120 s and <= 1.8 x; peak memory < 4 GB; every plan verifies.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _run(cmd: list[str], timeout_s: float) -> tuple[float, int, float, str, float]:
    """Wall time (s), exit code, child peak RSS (MB), stdout and CPU time (user + system, s) of
    one subprocess (CPU time shows the work when the shared machine is loaded)."""
    t0 = time.perf_counter()
    with tempfile.TemporaryFile() as out:
        proc = subprocess.Popen(cmd, stdout=out, stderr=subprocess.DEVNULL, cwd=ROOT)
        deadline = t0 + timeout_s
        while True:
            pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                break
            if time.perf_counter() > deadline:
                proc.kill()
                pid, status, usage = os.wait4(proc.pid, 0)
                break
            time.sleep(0.05)
        wall = time.perf_counter() - t0
        out.seek(0)
        text = out.read().decode(errors="replace")
    code = os.waitstatus_to_exitcode(status)
    cpu = usage.ru_utime + usage.ru_stime
    return wall, code, usage.ru_maxrss / 1024.0, text, cpu  # ru_maxrss is in KB on Linux


def _plan(scenario: Path, out: Path, method: str, timeout_s: float, lower_bound_s: float) -> dict:
    cmd = [sys.executable, "-m", "proxplan.cli", "plan", str(scenario), "--out", str(out)]
    cmd += ["--method", method, "--seed", "0", "--no-plot", "--json"]
    wall, code, rss_mb, text, cpu = _run(cmd, timeout_s)
    row: dict = {
        "wall_s": wall,
        "cpu_s": cpu,
        "exit": code,
        "peak_mb": rss_mb,
        "makespan_s": None,
        "ratio": None,
        "verify": "-",
    }
    if code != 0:
        row["verify"] = "timeout" if wall >= timeout_s else f"exit {code}"
        return row
    doc = json.loads(text)
    makespan = float(doc["metrics"]["makespan_s"])
    row.update({"makespan_s": makespan, "ratio": makespan / lower_bound_s, "method": doc.get("method")})
    res = subprocess.run(
        [sys.executable, "-m", "proxplan.cli", "verify", str(out / "plan.json")],
        capture_output=True,
        text=True,
        cwd=ROOT,
    )
    row["verify"] = "PASS" if res.returncode == 0 else "FAIL"
    return row


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, nargs="+", default=[8, 16, 32, 64, 128], help="swarm sizes")
    ap.add_argument("--optimized", action="store_true", help="also run --method optimized")
    ap.add_argument("--timeout", type=float, default=600.0, help="per-plan wall-time cap, s")
    args = ap.parse_args()

    import yaml

    from proxplan.planfile import load_scenario
    from proxplan.planner.formations import formation_change
    from proxplan.planner.ordering import lower_bound_makespan_s

    base_wall, _, base_mb, _, base_cpu = _run(
        [sys.executable, "-c", "import proxplan.planner.pipeline, proxplan.verify, ompl.geometric"], 120
    )
    print(f"baseline (interpreter + planner imports): {base_wall:.2f} s wall, {base_cpu:.2f} s CPU, {base_mb:.0f} MB")
    methods = ["sampling"] + (["optimized"] if args.optimized else [])
    head = f"{'N':>4s} {'method':9s} {'wall_s':>7s} {'x base':>7s} {'cpu_s':>6s} {'makespan':>8s} {'LB_s':>5s} {'ms/LB':>6s} {'peak_MB':>7s} verify"
    print(head)
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.n:
            path = Path(tmp) / f"formation-{n}.yaml"
            path.write_text(yaml.safe_dump(formation_change(n), sort_keys=False))
            lb = lower_bound_makespan_s(load_scenario(path))
            for method in methods:
                r = _plan(path, Path(tmp) / f"out-{n}-{method}", method, args.timeout, lb)
                ms = "-" if r["makespan_s"] is None else f"{r['makespan_s']:.2f}"
                ratio = "-" if r["ratio"] is None else f"{r['ratio']:.2f}"
                print(
                    f"{n:4d} {method:9s} {r['wall_s']:7.1f} {r['wall_s'] / base_wall:7.1f} {r['cpu_s']:6.1f} {ms:>8s} {lb:5.2f} "
                    f"{ratio:>6s} {r['peak_mb']:7.0f} {r['verify']}",
                    flush=True,
                )
    return 0


if __name__ == "__main__":
    sys.exit(main())
