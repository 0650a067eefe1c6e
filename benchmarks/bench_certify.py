"""Speed of ``proxplan certify`` on the battery swap: N closed-loop flights on the local default
(a Dask LocalCluster, one worker per core), against one plain ``simulate`` in the same run.

Plans scenarios/battery_swap.yaml (sampling, seed 0) into a temporary folder, then times
  * baseline: one ``proxplan.flightsim.simulate_plan`` of the plan in this process (stepper compiled first,
    so the figure is the flight itself), i.e. flights per second of plain serial simulation;
  * ``certify_plan`` with N runs (cluster start, draws, flights, reduction; report excluded),
and prints wall times, runs per second and the ratio to the baseline, and the CPU seconds spent
in all processes per run against one plain simulate (independent of other load on the machine:
the wall figure on idle cores follows from it).

Run: python benchmarks/bench_certify.py [--runs 200] [--workers K]
"""

from __future__ import annotations

import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def _cpu_s() -> float:
    """CPU seconds (user + system) of this process and of its finished, waited-for children
    (the local cluster's nanny and worker processes once it is closed)."""
    me = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return me.ru_utime + me.ru_stime + kids.ru_utime + kids.ru_stime


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=200)
    parser.add_argument("--workers", type=int, default=None, help="local workers (default: one per core)")
    args = parser.parse_args()

    from proxplan.certify import CertifySetup, certify_plan
    from proxplan.flightsim import plan_truth, simulate_plan
    from proxplan.planfile import read_plan
    from proxplan.verify import scenario_of_plan

    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run(
            [sys.executable, "-m", "proxplan.cli", "plan", str(REPO / "scenarios" / "battery_swap.yaml"),
             "--out", tmp, "--method", "sampling", "--json"],
            check=True, capture_output=True,
        )  # fmt: skip
        plan = read_plan(Path(tmp) / "plan.json")
    scenario = scenario_of_plan(plan)
    setup = CertifySetup(
        plan=plan,
        seed=0,
        authority_limit=scenario.limits.authority_fraction,
        min_separation_m=scenario.limits.min_separation_m,
        truth=plan_truth(plan),
    )
    simulate_plan(plan, options=setup.options)  # compile the stepper once
    t0 = time.perf_counter()
    simulate_plan(plan, options=setup.options)
    one = time.perf_counter() - t0
    print(f"baseline: one plain simulate of the battery swap: {one:.3f} s ({1.0 / one:.2f} flights/s serial)")

    one_cpu = _cpu_s()
    simulate_plan(plan, options=setup.options)
    one_cpu = _cpu_s() - one_cpu

    t0 = time.perf_counter()
    cpu0 = _cpu_s()
    result = certify_plan(setup, args.runs, n_workers=args.workers)
    wall = time.perf_counter() - t0
    cpu = _cpu_s() - cpu0  # this process (scheduler, client) + the finished worker processes
    rate = args.runs / wall
    workers = result.execution["workers"]
    print(
        f"certify: {args.runs} runs on {workers} local worker(s) in {wall:.1f} s "
        f"({rate:.2f} runs/s, {rate * one:.2f}x the plain-simulate rate; target < 60 s for 200 runs)"
    )
    print(
        f"  CPU: {cpu:.1f} s in all processes = {cpu / max(args.runs, 1):.3f} s per run vs {one_cpu:.3f} s for one "
        f"plain simulate ({cpu / max(args.runs, 1) / one_cpu:.2f}x); on {os.cpu_count()} idle cores that is "
        f"~{cpu / min(workers, os.cpu_count() or 1):.0f} s wall (load average now {os.getloadavg()[0]:.1f})"
    )
    s = result.summary
    print(
        f"  P(authority exceeded) = {s['p_authority_exceeded']:.3f} {s['ci95']['authority_exceeded']}, "
        f"P(separation violated) = {s['p_separation_violated']:.3f}, P(goal missed) = {s['p_goal_missed']:.3f}, "
        f"tracking p50/p95/max = {s['tracking_error_m']['p50']:.3f}/{s['tracking_error_m']['p95']:.3f}/"
        f"{s['tracking_error_m']['max']:.3f} m, retried runs {result.execution['retried_runs']}"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
