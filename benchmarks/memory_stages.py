"""Where the memory (and CPU) of one ``plan_scenario`` goes, stage by stage, in one process.

Plans a named layout as the bench's child does (``plan_scenario(method=..., seed=0)``, then ``verify_plan``
where the plan is not verified yet) with the pipeline's and the swarm layer's stage functions wrapped
(looked up where they are called, so nothing of the planner changes), and prints one row per call, nested
by depth: CPU s (``time.process_time``, this process), resident memory (RSS, MB, from ``/proc/self/statm``)
on entry and on exit, and the peak RSS sampled every 20 ms while the call ran. ``--cpu-cap S`` stops the
plan after S s of CPU (``RLIMIT_CPU``'s SIGXCPU; the calls still open are marked ``cut``), so a size
that gives no plan still shows where it got to. ``--tracemalloc`` also traces Python's allocations (1
frame; slower: use it at 64-128) and prints the top allocation sites of the snapshot taken at the stage
exit where the most memory was traced, and what each stage left allocated.

Usage (from outside the repository so that the interpreter's installed proxplan is imported):
    cd /tmp && PY /path/to/benchmarks/memory_stages.py --layout grid --n 128 [--method swarm]
        [--assign fixed|by_type] [--cpu-cap 300] [--tracemalloc]

Figures are of this process only (the swarm layer's Dask workers, when it fans groups out, are not in
them); RSS includes memory freed by Python but kept by the allocator.
"""

from __future__ import annotations

import argparse
import gc
import importlib
import os
import resource
import signal
import sys
import threading
import time
import tracemalloc
from dataclasses import dataclass, field

PAGE_MB = os.sysconf("SC_PAGE_SIZE") / 2**20
SAMPLE_S = 0.02  # RSS sampling period of the peak column, s
# (module, function) pairs wrapped where they are looked up: the pipeline's stages, the verifier, the
# swarm layer's stages (swarm/plan.py's namespace, so the stacked plan's levels show nested)
WRAPPED = (
    ("proxplan.planner.pipeline", "swarm_timed"),
    ("proxplan.planner.pipeline", "assemble_plan"),
    ("proxplan.planner.pipeline", "deflection_allowance"),
    ("proxplan.planner.pipeline", "sampling_plan"),
    ("proxplan.planner.pipeline", "refine_stage"),
    ("proxplan.planner.pipeline", "certified_bound"),
    ("proxplan.planner.pipeline", "finish_metrics"),
    ("proxplan.verify", "verify_with_deflections"),
    ("proxplan.verify", "verify_plan"),
    ("proxplan.verify.checks", "plan_samples"),
    ("proxplan.verify.checks", "wrench_along_plan"),
    ("proxplan.verify.checks", "loop_along_plan"),
    ("proxplan.verify.checks", "check_jet_loop"),
    ("proxplan.verify.checks", "check_pairs"),
    ("proxplan.verify.checks", "check_authority"),
    ("proxplan.verify.checks", "check_authority_tube"),
    ("proxplan.planner.swarm.plan", "swarm_problem"),
    ("proxplan.planner.swarm.plan", "straight_step_conflicts"),
    ("proxplan.planner.swarm.plan", "kept_straight_stage"),
    ("proxplan.planner.swarm.plan", "prioritised_stage"),
    ("proxplan.planner.swarm.plan", "lattice_stage"),
    ("proxplan.planner.swarm.plan", "stacking_keepouts"),
    ("proxplan.planner.swarm.plan", "stack_levels"),
    ("proxplan.planner.swarm.plan", "join_levels"),
    ("proxplan.planner.swarm.plan", "gave_up"),
    ("proxplan.planner.swarm.plan", "_retime_stage"),
    ("proxplan.planner.swarm.plan", "heights_pass"),
    ("proxplan.planner.swarm.plan", "_makespan_stage"),
    ("proxplan.planner.swarm.plan", "_handed_on"),
)


class CpuCap(BaseException):
    """Raised by SIGXCPU (a BaseException: the planner's ``except Exception`` does not catch it)."""


def rss_mb() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * PAGE_MB


@dataclass
class Call:
    name: str
    depth: int
    cpu0: float
    rss0: float
    peak: float
    cpu: float = 0.0
    rss1: float | None = None  # None: cut by the CPU cap
    traced_mb: float | None = None  # tracemalloc's current on exit, MB
    notes: list[str] = field(default_factory=list)


class Recorder:
    def __init__(self, trace: bool, live: bool):
        self.live = live
        self.calls: list[Call] = []
        self.open: list[Call] = []
        self.trace = trace
        self.best_snapshot: tracemalloc.Snapshot | None = None
        self.best_traced = -1.0
        self.best_at = ""
        self._stop = threading.Event()
        self._sampler = threading.Thread(target=self._sample, daemon=True)
        self._sampler.start()

    def _sample(self) -> None:
        while not self._stop.wait(SAMPLE_S):
            r = rss_mb()
            for c in list(self.open):
                if r > c.peak:
                    c.peak = r

    def wrap(self, name: str, fn):
        rec = self

        def wrapped(*args, **kwargs):
            call = Call(name, len(rec.open), time.process_time(), rss_mb(), rss_mb())
            rec.calls.append(call)
            rec.open.append(call)
            if rec.live:
                print(f"> {'  ' * call.depth}{name} RSS {call.rss0:.0f} MB, CPU {call.cpu0:.1f} s", flush=True)
            try:
                return fn(*args, **kwargs)
            finally:
                rec.open.remove(call)
                call.cpu = time.process_time() - call.cpu0
                if not isinstance(sys.exc_info()[1], CpuCap):
                    call.rss1 = rss_mb()
                    call.peak = max(call.peak, call.rss1)
                    if rec.live:
                        print(
                            f"< {'  ' * call.depth}{name} {call.cpu:.1f} s CPU, RSS {call.rss1:.0f} MB, peak {call.peak:.0f}",
                            flush=True,
                        )
                    if rec.trace:
                        cur, _ = tracemalloc.get_traced_memory()
                        call.traced_mb = cur / 2**20
                        if cur / 2**20 > rec.best_traced and call.depth <= 2:
                            rec.best_traced = cur / 2**20
                            rec.best_at = f"exit of {name} (depth {call.depth})"
                            rec.best_snapshot = tracemalloc.take_snapshot()

        wrapped.__wrapped__ = fn
        return wrapped

    def stop(self) -> None:
        self._stop.set()


def instrument(rec: Recorder) -> None:
    for mod_name, attr in WRAPPED:
        mod = importlib.import_module(mod_name)
        if hasattr(mod, attr):
            setattr(mod, attr, rec.wrap(f"{mod_name.rsplit('.', 1)[-1]}.{attr}", getattr(mod, attr)))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--layout", default="grid")
    ap.add_argument("--n", type=int, default=64)
    ap.add_argument("--method", default="swarm")
    ap.add_argument("--assign", choices=("fixed", "by_type"), default="fixed")
    ap.add_argument("--cpu-cap", type=float, default=None, help="stop the plan after this much CPU, s")
    ap.add_argument("--tracemalloc", action="store_true", help="trace Python allocations (slower)")
    ap.add_argument("--live", action="store_true", help="also print each call as it starts and ends")
    ap.add_argument("--top", type=int, default=15, help="allocation sites printed with --tracemalloc")
    args = ap.parse_args()

    import proxplan
    from proxplan.planfile.scenario_load import scenario_from_dict
    from proxplan.planner.formations import layout_doc

    print(f"proxplan from {proxplan.__file__}")
    scenario = scenario_from_dict(layout_doc(args.layout, args.n, assign=args.assign))
    rec = Recorder(args.tracemalloc, args.live)
    instrument(rec)
    import proxplan.planner.pipeline as pipeline
    import proxplan.verify as verify

    if args.tracemalloc:
        tracemalloc.start(1)

    def on_cap(signum, frame):
        raise CpuCap()

    outcome = "plan"
    cpu_start = time.process_time()
    if args.cpu_cap is not None:
        signal.signal(signal.SIGXCPU, on_cap)
        soft = int(cpu_start + args.cpu_cap) + 1
        resource.setrlimit(resource.RLIMIT_CPU, (soft, resource.getrlimit(resource.RLIMIT_CPU)[1]))
    rss_start = rss_mb()
    t0 = time.perf_counter()
    try:
        plan = pipeline.plan_scenario(scenario, method=args.method, seed=0)
        if not plan.verified:
            verify.verify_plan(plan, scenario)
        outcome = f"plan {plan.method} verified={plan.verified} makespan {plan.metrics.get('makespan_s')}"
    except CpuCap:
        outcome = f"stopped by the CPU cap ({args.cpu_cap:g} s)"
    except Exception as err:  # noqa: BLE001 - a benchmark reports what ended the plan
        outcome = f"{type(err).__name__}: {err}"
    finally:
        if args.cpu_cap is not None:
            hard = resource.getrlimit(resource.RLIMIT_CPU)[1]
            resource.setrlimit(resource.RLIMIT_CPU, (hard, hard))
    wall = time.perf_counter() - t0
    rec.stop()
    print(f"{args.layout}-{args.n} {args.method} {args.assign}: {outcome}")
    print(
        f"wall {wall:.1f} s, CPU {time.process_time() - cpu_start:.1f} s, RSS at start {rss_start:.0f} MB, "
        f"peak RSS of the process {resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024:.0f} MB"
    )
    head = f"{'stage':<48s} {'CPU_s':>7s} {'RSS_in':>7s} {'RSS_out':>7s} {'peak':>7s} {'+peak':>7s}"
    if args.tracemalloc:
        head += f" {'traced':>7s}"
    print(head)
    for c in rec.calls:
        out = "cut" if c.rss1 is None else f"{c.rss1:7.0f}"
        row = (
            f"{'  ' * c.depth + c.name:<48s} {c.cpu:7.1f} {c.rss0:7.0f} {out:>7s} {c.peak:7.0f} {c.peak - c.rss0:7.0f}"
        )
        if args.tracemalloc:
            row += f" {c.traced_mb:7.0f}" if c.traced_mb is not None else f" {'-':>7s}"
        print(row)
    if rec.best_snapshot is not None:
        print(f"\ntop allocation sites at the {rec.best_at}: {rec.best_traced:.0f} MB traced")
        for stat in rec.best_snapshot.statistics("lineno")[: args.top]:
            frame = stat.traceback[0]
            where = frame.filename.split("site-packages/")[-1].split("/wtA/")[-1]
            print(f"  {stat.size / 2**20:8.1f} MB {stat.count:9d} blocks  {where}:{frame.lineno}")
    gc.collect()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
