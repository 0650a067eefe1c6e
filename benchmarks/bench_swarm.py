"""Swarm benchmark (issue 30): formation layouts of N vehicles planned by ``proxplan plan`` in fresh
processes, fixed goals and interchangeable goals (``assign_goals: by_type``).

Usage:
    python benchmarks/bench_swarm.py [--layout pillar grid circle corridor] [--n 32 64 128 256]
        [--method optimized swarm sampling] [--assign fixed by_type] [--timeout 600]

Layouts (``proxplan.planner.formations.LAYOUTS``): ``pillar`` two staggered layers west of a pillar
swap layers to the east side; ``grid`` a grid reshuffled by a seeded permutation; ``circle`` every
vehicle to the antipode (all paths cross the centre); ``corridor`` two groups trade sides through a
gap in a wall. Vehicle types cycle Crazyflie 2.1, Crazyflie-Parrot, small quad (``--types`` to change).

Per run it prints the whole ``proxplan plan`` process's wall and CPU time (s; the interpreter +
import baseline of the same run is printed first, so compare ratios on a loaded machine), the
makespan against the lower bound (fixed goals: the largest straight-line rest-to-rest time of any
vehicle; ``by_type``: the same under the assignment, ``assignment_lower_bound_s``), the plan's
method and how the swarm layer coordinated, the child's peak memory (``resource`` rusage, MB), and
the verdict and whole-process time of ``proxplan verify`` on the written plan.json.
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
    """Wall time (s), exit code, child peak RSS (MB), stdout and CPU time (user + system, s)."""
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
    return wall, os.waitstatus_to_exitcode(status), usage.ru_maxrss / 1024.0, text, usage.ru_utime + usage.ru_stime


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--layout", nargs="+", default=["pillar", "grid", "circle", "corridor"])
    ap.add_argument("--n", type=int, nargs="+", default=[32, 64, 128, 256], help="swarm sizes")
    ap.add_argument("--method", nargs="+", default=["optimized"], choices=["optimized", "swarm", "sampling"])
    ap.add_argument("--assign", nargs="+", default=["fixed"], choices=["fixed", "by_type"])
    ap.add_argument("--types", default=None, help="comma-separated vehicle types (default: the layout's mix)")
    ap.add_argument("--timeout", type=float, default=600.0, help="per-run wall-time cap, s")
    ap.add_argument("--keep", default=None, metavar="DIR", help="keep scenarios and plans in DIR")
    args = ap.parse_args()

    import yaml

    from proxplan.planfile import load_scenario
    from proxplan.planner.formations import LAYOUTS
    from proxplan.planner.sampling.ordering import lower_bound_makespan_s

    base_wall, _, base_mb, _, base_cpu = _run([sys.executable, "-m", "proxplan.cli", "--help"], 120)
    print(f"baseline (interpreter + CLI start): {base_wall:.2f} s wall, {base_cpu:.2f} s CPU, {base_mb:.0f} MB")
    print(
        f"{'layout':9s} {'N':>4s} {'goals':8s} {'method':10s} {'wall_s':>7s} {'cpu_s':>6s} {'makespan':>8s} "
        f"{'LB_s':>6s} {'ms/LB':>6s} {'peak_MB':>7s} {'verify':>6s} {'verify_s':>8s}  how"
    )
    tmp_ctx = tempfile.TemporaryDirectory() if args.keep is None else None
    tmp = Path(args.keep) if args.keep else Path(tmp_ctx.name)  # type: ignore[union-attr]
    tmp.mkdir(parents=True, exist_ok=True)
    for layout in args.layout:
        for n in args.n:
            for goals in args.assign:
                kw = {"types": args.types.split(",")} if args.types else {}
                doc = LAYOUTS[layout](n, **kw)
                if goals == "by_type":
                    doc["assign_goals"] = "by_type"
                path = tmp / f"{layout}-{n}-{goals}.yaml"
                path.write_text(yaml.safe_dump(doc, sort_keys=False))
                lb = lower_bound_makespan_s(load_scenario(path))
                for method in args.method:
                    out = tmp / f"out-{layout}-{n}-{goals}-{method}"
                    cmd = [sys.executable, "-m", "proxplan.cli", "plan", str(path), "--out", str(out)]
                    cmd += ["--method", method, "--seed", "0", "--no-plot", "--json"]
                    wall, code, mb, text, cpu = _run(cmd, args.timeout)
                    ms = ratio = "-"
                    verdict, v_wall, how = ("timeout" if wall >= args.timeout else f"exit {code}"), "-", ""
                    lb_used = lb
                    if code == 0:
                        doc_out = json.loads(text.strip().splitlines()[-1])
                        m = doc_out["metrics"]
                        lb_used = float(m.get("assignment_lower_bound_s") or lb)
                        makespan = float(m["makespan_s"])
                        ms, ratio = f"{makespan:.2f}", f"{makespan / lb_used:.2f}"
                        how = f"{doc_out['method']}: " + str((m.get("swarm") or {}).get("coordination", ""))[:60]
                        t_v = time.perf_counter()
                        res = subprocess.run(
                            [sys.executable, "-m", "proxplan.cli", "verify", str(out / "plan.json")],
                            capture_output=True,
                            cwd=ROOT,
                        )
                        v_wall = f"{time.perf_counter() - t_v:.1f}"
                        verdict = "PASS" if res.returncode == 0 else "FAIL"
                    elif text.strip():
                        try:
                            how = json.loads(text.strip().splitlines()[-1]).get("message", "")[:80]
                        except json.JSONDecodeError:
                            how = text.strip()[-80:]
                    print(
                        f"{layout:9s} {n:4d} {goals:8s} {method:10s} {wall:7.1f} {cpu:6.1f} {ms:>8s} {lb_used:6.2f} "
                        f"{ratio:>6s} {mb:7.0f} {verdict:>6s} {v_wall:>8s}  {how}",
                        flush=True,
                    )
    if tmp_ctx is not None:
        tmp_ctx.cleanup()
    return 0


if __name__ == "__main__":
    sys.exit(main())
