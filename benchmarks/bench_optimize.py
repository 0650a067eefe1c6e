"""Benchmark of the CasADi refinement (proxplan.planner.optimizer) on shipped scenarios.

    python benchmarks/bench_optimize.py [--scenarios battery_swap swap_8] [--exact]
    python benchmarks/bench_optimize.py --formations 8 16 32 [--time-budget 60]

Prints, per scenario: the whole-process wall time of ``proxplan plan --method optimized`` and of
``--method sampling`` (baseline, same run) and their ratio; the in-process IPOPT solve time,
iterations and variables; the makespans of both. With ``--exact`` it also times the refinement
with the exact (MX, non-expanded) wrench table instead of its sequential linearisation, as a
ratio against the default. With ``--formations N ...`` it plans formation changes of N vehicles
(``proxplan.planner.formations``) instead and prints the whole-process time and peak memory (RSS of the
child) of both methods, the optimised makespan as a ratio of sampling's, and what the optimiser
said. Numbers are printed, never asserted.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


# runs the command and prints the child's peak RSS (KiB) as the last stderr line
_RSS_WRAPPER = (
    "import resource, subprocess, sys; r = subprocess.run(sys.argv[1:]); "
    "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss, file=sys.stderr); sys.exit(r.returncode)"
)


def whole_process(scenario: Path, method: str, extra: tuple[str, ...] = ()) -> tuple[float, dict]:
    with tempfile.TemporaryDirectory() as out:
        t0 = time.perf_counter()
        command = [sys.executable, "-m", "proxplan.cli", "plan", str(scenario), "--out", out, "--method", method]
        proc = subprocess.run(
            [sys.executable, "-c", _RSS_WRAPPER, *command, "--json", "--no-plot", *extra],
            capture_output=True,
            text=True,
            cwd=ROOT,
        )
        wall = time.perf_counter() - t0
    if proc.returncode != 0:
        return wall, {
            "error": proc.stderr.strip().splitlines()[-1] if proc.stderr.strip() else f"exit {proc.returncode}"
        }
    doc = json.loads(proc.stdout)
    doc["peak_rss_mb"] = int(proc.stderr.strip().splitlines()[-1]) / 1024.0
    return wall, doc


def formations(sizes: list[int], budget: float | None) -> None:
    import yaml

    from proxplan.planner.formations import formation_change

    extra = () if budget is None else ("--time-budget", str(budget))
    print(
        f"{'N':>4s} {'optimized s':>11s} {'MB':>6s} {'sampling s':>10s} {'MB':>6s} "
        f"{'makespan opt / samp (s)':>24s} {'ratio':>6s} {'verify':>6s}  method"
    )
    with tempfile.TemporaryDirectory() as tmp:
        for n in sizes:
            path = Path(tmp) / f"formation-{n}.yaml"
            path.write_text(yaml.safe_dump(formation_change(n), sort_keys=False))
            t_opt, opt = whole_process(path, "optimized", extra)
            t_smp, smp = whole_process(path, "sampling")
            if "error" in opt or "error" in smp:
                print(f"{n:4d} failed: {opt.get('error') or smp.get('error')}")
                continue
            m_opt, m_smp = opt["metrics"]["makespan_s"], smp["metrics"]["makespan_s"]
            print(
                f"{n:4d} {t_opt:11.1f} {opt['peak_rss_mb']:6.0f} {t_smp:10.1f} {smp['peak_rss_mb']:6.0f} "
                f"{m_opt:13.2f} / {m_smp:.2f} {m_opt / m_smp:6.3f} {str(opt['verify']['passed']):>6s}  {opt['method']}"
            )
            print(f"     {[n for n in opt['notes'] if n.startswith('optimized')][-1:]}")


def in_process(scenario_path: Path, *, exact: bool) -> dict:
    from proxplan.planfile import load_scenario
    from proxplan.planner import plan_scenario
    from proxplan.planner.optimizer import build_and_solve, build_problem, moving_end_s, solution_to_plan
    from proxplan.verify import verify_plan

    scenario = load_scenario(scenario_path)
    initial = plan_scenario(scenario, method="sampling", seed=0)
    problem = build_problem(scenario, initial)
    out = {}
    variants = [("linearised", problem)]
    if exact:
        variants.append(("exact-MX", dataclasses.replace(problem, linearize=False)))
    for label, pb in variants:
        t0 = time.perf_counter()
        sol = build_and_solve(pb)
        wall = time.perf_counter() - t0
        plan = solution_to_plan(sol, scenario, initial)
        out[label] = {
            "status": sol.status,
            "iterations": sol.iterations,
            "solve_s": sol.solve_time_s,
            "wall_s": wall,
            "makespan_s": moving_end_s(plan),
            "violations": len(verify_plan(plan, scenario)) if sol.success else None,
            "intervals": pb.n_intervals,
        }
    out["sampling_makespan_s"] = moving_end_s(initial)
    return out


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", nargs="*", default=["battery_swap", "swap_8"])
    parser.add_argument("--exact", action="store_true", help="also time the exact MX table formulation")
    parser.add_argument("--formations", nargs="*", type=int, help="formation changes of these sizes instead")
    parser.add_argument("--time-budget", type=float, default=None, help="optimiser budget, s (plan --time-budget)")
    args = parser.parse_args()
    if args.formations:
        formations(args.formations, args.time_budget)
        return 0
    print(
        f"{'scenario':16s} {'optimized s':>11s} {'sampling s':>10s} {'ratio':>6s}  {'IPOPT s':>8s} {'iter':>5s} "
        f"{'makespan opt / samp (s)':>24s}"
    )
    for name in args.scenarios:
        path = ROOT / "scenarios" / f"{name}.yaml"
        t_opt, res_opt = whole_process(path, "optimized")
        t_smp, res_smp = whole_process(path, "sampling")
        if "error" in res_opt or "error" in res_smp:
            print(f"{name:16s} failed: {res_opt.get('error') or res_smp.get('error')}")
            continue
        m = res_opt["metrics"]
        print(
            f"{name:16s} {t_opt:11.2f} {t_smp:10.2f} {t_opt / t_smp:6.1f}  "
            f"{m.get('optimizer_solve_time_s') or float('nan'):8.2f} {m.get('optimizer_iterations') or 0:5d} "
            f"{m['makespan_s']:13.2f} / {res_smp['metrics']['makespan_s']:.2f}   ({res_opt['method']})"
        )
        if args.exact:
            inner = in_process(path, exact=True)
            lin, ex = inner["linearised"], inner["exact-MX"]
            print(
                f"  in-process, n={lin['intervals']}: linearised {lin['wall_s']:.2f} s ({lin['iterations']} it, "
                f"makespan {lin['makespan_s']:.2f} s, {lin['violations']} violations) vs exact MX {ex['wall_s']:.2f} s "
                f"({ex['iterations']} it, {ex['status']}, makespan {ex['makespan_s']:.2f} s): ratio {ex['wall_s'] / lin['wall_s']:.1f}"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
