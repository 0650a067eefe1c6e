"""Swarm benchmark (issues 14, 21): layouts of N vehicles planned on the shared roadmap (PBS or PP)
and, optionally, by the sampling planner, each in its own process.

Usage:
    python benchmarks/bench_swarm.py [--layout pillar grid circle corridor] [--n 32 64 128 256]
        [--search pbs pp] [--sampling] [--timeout 600]

Layouts (``proxplan.planner.formations.LAYOUTS``, generated in code): ``pillar`` two staggered
layers west of a pillar swap layers to the east side; ``grid`` a grid reshuffled by a seeded
permutation; ``circle`` every vehicle to the antipode (all paths cross the centre); ``corridor`` two
groups trade sides through a gap in a wall. Vehicle types cycle Crazyflie 2.1, Crazyflie-Parrot,
small quad (``--types`` to change).

Per run it prints whole-process wall and CPU time (s; the interpreter + import baseline of the
same run is printed first), makespan / lower bound (largest straight-line rest-to-rest time of any
vehicle, ``proxplan.planner.sampling.ordering.lower_bound_makespan_s``), sum of costs (sum of arrival
times, s), peak memory (``resource`` rusage of the child, MB) and the verdict of ``proxplan
verify`` on the written plan.json. A roadmap run that finds no plan prints its message; the
roadmap child does not fall back to sampling (``proxplan plan --method roadmap`` would).
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


def child(scenario: str, out: str, search: str) -> int:
    """Plan on the roadmap, write plan.json, print one JSON line of metrics (no fall-back)."""
    from proxplan.planfile import load_scenario, write_plan
    from proxplan.planner import InfeasibleError
    from proxplan.planner.pipeline import finish_metrics, plan_roadmap
    from proxplan.planner.swarm.plan import RoadmapOptions

    t0 = time.perf_counter()
    sc = load_scenario(scenario)
    try:
        plan = plan_roadmap(sc, RoadmapOptions(search=search))
    except InfeasibleError as err:
        print(json.dumps({"feasible": False, "message": err.message}))
        return 1
    finish_metrics(sc, plan, planning_time_s=time.perf_counter() - t0)
    Path(out).mkdir(parents=True, exist_ok=True)
    write_plan(plan, out)
    info = plan.metrics["roadmap"]
    print(json.dumps({"feasible": True, "makespan_s": plan.metrics["makespan_s"], "roadmap": info}))
    return 0


def _verify(plan_json: Path) -> str:
    res = subprocess.run(
        [sys.executable, "-m", "proxplan.cli", "verify", str(plan_json)], capture_output=True, cwd=ROOT
    )
    return "PASS" if res.returncode == 0 else "FAIL"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--layout", nargs="+", default=["pillar", "grid", "circle", "corridor"])
    ap.add_argument("--n", type=int, nargs="+", default=[32, 64, 128, 256], help="swarm sizes")
    ap.add_argument("--search", nargs="+", default=["pbs"], choices=["pbs", "pp"])
    ap.add_argument("--sampling", action="store_true", help="also run proxplan plan --method sampling")
    ap.add_argument("--types", default=None, help="comma-separated vehicle types (default: the layout's mix)")
    ap.add_argument("--timeout", type=float, default=600.0, help="per-run wall-time cap, s")
    ap.add_argument("--child", nargs=3, metavar=("SCENARIO", "OUT", "SEARCH"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        return child(*args.child)

    import yaml

    from proxplan.planfile import load_scenario
    from proxplan.planner.formations import LAYOUTS
    from proxplan.planner.sampling.ordering import lower_bound_makespan_s

    base_wall, _, base_mb, _, base_cpu = _run(
        [sys.executable, "-c", "import proxplan.planner.pipeline, proxplan.planner.swarm.plan, proxplan.verify"], 120
    )
    print(f"baseline (interpreter + planner imports): {base_wall:.2f} s wall, {base_cpu:.2f} s CPU, {base_mb:.0f} MB")
    print(
        f"{'layout':9s} {'N':>4s} {'method':12s} {'wall_s':>7s} {'cpu_s':>6s} {'makespan':>8s} {'LB_s':>6s} "
        f"{'ms/LB':>6s} {'SoC_s':>8s} {'peak_MB':>7s} verify"
    )
    with tempfile.TemporaryDirectory() as tmp:
        for layout in args.layout:
            for n in args.n:
                kw = {"types": args.types.split(",")} if args.types else {}
                path = Path(tmp) / f"{layout}-{n}.yaml"
                path.write_text(yaml.safe_dump(LAYOUTS[layout](n, **kw), sort_keys=False))
                lb = lower_bound_makespan_s(load_scenario(path))
                runs = [(f"roadmap-{s}", s) for s in args.search] + ([("sampling", None)] if args.sampling else [])
                for label, search in runs:
                    out = Path(tmp) / f"out-{layout}-{n}-{label}"
                    if search:
                        cmd = [sys.executable, str(Path(__file__).resolve()), "--child", str(path), str(out), search]
                    else:
                        cmd = [sys.executable, "-m", "proxplan.cli", "plan", str(path), "--out", str(out)]
                        cmd += ["--method", "sampling", "--seed", "0", "--no-plot", "--json"]
                    wall, code, mb, text, cpu = _run(cmd, args.timeout)
                    ms = soc = "-"
                    ratio = "-"
                    verdict = "timeout" if wall >= args.timeout else f"exit {code}"
                    if code == 0:
                        doc = json.loads(text.strip().splitlines()[-1])
                        makespan = float(doc.get("makespan_s") or doc["metrics"]["makespan_s"])
                        ms, ratio = f"{makespan:.2f}", f"{makespan / lb:.2f}"
                        if "roadmap" in doc:
                            soc = f"{doc['roadmap']['sum_of_costs_s']:.1f}"
                        verdict = _verify(out / "plan.json")
                    elif search and text.strip():
                        verdict += ": " + json.loads(text.strip().splitlines()[-1]).get("message", "")[:70]
                    print(
                        f"{layout:9s} {n:4d} {label:12s} {wall:7.1f} {cpu:6.1f} {ms:>8s} {lb:6.2f} {ratio:>6s} "
                        f"{soc:>8s} {mb:7.0f} {verdict}",
                        flush=True,
                    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
