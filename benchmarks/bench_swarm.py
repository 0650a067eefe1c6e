"""Swarm benchmark: formation changes of N vehicles planned by ``proxplan plan`` in fresh processes,
fixed goals and interchangeable goals (``assign_goals: by_type``), on the named layouts and on a
seeded family of random layouts.

Usage:
    python benchmarks/bench_swarm.py [--layout pillar grid circle corridor] [--family K [--family-seed S]]
        [--n 32 64 128 256] [--method optimized swarm sampling] [--assign fixed by_type] [--timeout 600]
        [--cpu-cap S] [--child-python PATH [PATH ...]] [--child-method-roadmap [PATH ...]] [--swarm-options JSON [JSON ...]]
        [--keep DIR]

Layouts (``proxplan.planner.formations.LAYOUTS``): ``pillar`` two staggered layers west of a pillar
swap layers to the east side; ``grid`` a grid reshuffled by a seeded permutation; ``circle`` every
vehicle to the antipode (all paths cross the centre); ``corridor`` two groups trade sides through a
gap in a wall. Vehicle types cycle Crazyflie 2.1, Crazyflie-Parrot, small quad (``--types`` to change).
``--family K`` adds K layouts of ``proxplan.planner.formations.random_formation`` (seeds S..S+K-1:
pitch, layers, obstacles, type mix, start and goal regions drawn at random). The swarm layer's
parameters were set on the named layouts only; report the family as it comes.

Per run it prints the whole ``proxplan plan`` process's wall and CPU time (s; the interpreter +
import baseline of the same run is printed first, so compare ratios on a loaded machine), the
makespan against the lower bound (fixed goals: the largest straight-line rest-to-rest time of any
vehicle, tabulated; ``by_type``: the same under the assignment, ``assignment_lower_bound_s``), and
beside it, with fixed goals, the certified bound of ``proxplan.planner.bounds.certified_bound``
(columns ``cLB_s`` and ``ms/cLB``: straight lines at Ruckig's exact optimum, routes round obstacles,
throughput through an obstacle's slab; docs/planner.md, round 16A; ``-`` with by_type), the plan's
method and how the swarm layer coordinated, the child's peak memory (``resource`` rusage, MB), and
the verdict and whole-process time of ``proxplan verify`` on the written plan.json, and how many
times the verification policy planned (``planned 2x``: the first plan failed ``verify`` and the
plan's notes say "planned again"). ``--cpu-cap S``
stops a run after S s of CPU time (its process tree) as well as after ``--timeout`` of wall time:
on a shared machine the CPU cap is the same for every run. Column ``arm``:
interpreter index x number of option sets + option set index.

``--child-python PATH [PATH ...]`` plans and verifies with these interpreters (other installed
versions of proxplan), each case with each of them in turn, so before and after share one run and
the same load; each interpreter's start-up baseline is printed first. ``--child-method-roadmap
[PATH ...]``: these interpreters (all, without a path) call the swarm method ``roadmap`` (versions
before the rename). ``--swarm-options JSON [JSON ...]`` plans in a child of this script with
``plan_scenario(..., swarm_options=SwarmOptions(**JSON))`` instead of the CLI, each case with each
option set in turn (to measure one cause at a time against ``{}``, the defaults, e.g.
``{"through_waypoints": "always"}``; the key ``sampling_alternative: false`` leaves out the
sampling planner beside the swarm layer); its wall time then includes the same verification and
writing as ``proxplan plan``, not the PNG (neither does the CLI run: ``--no-plot``).
Children run outside the repository (from its root, ``import proxplan`` would find the checkout).
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import psutil

ROOT = Path(__file__).resolve().parents[1]


def _tree_cpu_s(proc: psutil.Process) -> float:
    """CPU time (user + system, s) of ``proc`` and its live descendants (Dask workers included)."""
    total = 0.0
    for p in [proc, *proc.children(recursive=True)]:
        try:
            t = p.cpu_times()
            total += t.user + t.system
        except psutil.Error:
            pass
    return total


def _run(cmd: list[str], timeout_s: float, cpu_cap_s: float | None = None) -> tuple[float, int, float, str, float]:
    """Wall time (s), exit code, child peak RSS (MB), stdout and CPU time (user + system, s). The child
    is killed after ``timeout_s`` of wall time or, when given, ``cpu_cap_s`` of CPU time of its process
    tree (a cap that does not depend on how loaded a shared machine is)."""
    t0 = time.perf_counter()
    with tempfile.TemporaryFile() as out:
        proc = subprocess.Popen(cmd, stdout=out, stderr=subprocess.DEVNULL, cwd=tempfile.gettempdir())
        watch = psutil.Process(proc.pid)
        deadline = t0 + timeout_s
        while True:
            pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                break
            over_cpu = cpu_cap_s is not None and _tree_cpu_s(watch) > cpu_cap_s
            if over_cpu or time.perf_counter() > deadline:
                for p in watch.children(recursive=True):
                    p.kill()
                proc.kill()
                pid, status, usage = os.wait4(proc.pid, 0)
                break
            time.sleep(0.25)
        wall = time.perf_counter() - t0
        out.seek(0)
        text = out.read().decode(errors="replace")
    return wall, os.waitstatus_to_exitcode(status), usage.ru_maxrss / 1024.0, text, usage.ru_utime + usage.ru_stime


def _child(scenario: str, out: str, method: str, options_json: str) -> int:
    """Plan ``scenario`` with swarm options, write plan.json and print the CLI's JSON line."""
    from proxplan.planfile import load_scenario, write_plan
    from proxplan.planner import plan_scenario
    from proxplan.planner.swarm import SwarmOptions
    from proxplan.verify import verify_plan

    sc = load_scenario(scenario)
    options = json.loads(options_json)
    alternative = options.pop("sampling_alternative", True)
    plan = plan_scenario(
        sc, method=method, seed=0, swarm_options=SwarmOptions(**options), sampling_alternative=alternative
    )
    violations = [] if plan.verified else verify_plan(plan, sc)
    plan.metrics["verify_violations"] = len(violations)
    Path(out).mkdir(parents=True, exist_ok=True)
    write_plan(plan, out)
    from proxplan.planfile import jsonable

    print(json.dumps({"feasible": True, "method": plan.method, "metrics": jsonable(plan.metrics)}))
    return 0


def main() -> int:
    if len(sys.argv) > 1 and sys.argv[1] == "--child":
        return _child(*sys.argv[2:6])
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--layout", nargs="*", default=["pillar", "grid", "circle", "corridor"])
    ap.add_argument("--family", type=int, default=0, help="also K random layouts of the seeded family")
    ap.add_argument("--family-seed", type=int, default=0, help="first seed of the family")
    ap.add_argument("--n", type=int, nargs="+", default=[32, 64, 128, 256], help="swarm sizes")
    ap.add_argument("--method", nargs="+", default=["optimized"], choices=["optimized", "swarm", "sampling"])
    ap.add_argument("--assign", nargs="+", default=["fixed"], choices=["fixed", "by_type"])
    ap.add_argument("--types", default=None, help="comma-separated vehicle types (default: the layout's mix)")
    ap.add_argument("--timeout", type=float, default=600.0, help="per-run wall-time cap, s")
    ap.add_argument("--cpu-cap", type=float, default=None, help="per-run CPU-time cap of the child's processes, s")
    ap.add_argument(
        "--child-python", nargs="+", default=[sys.executable], help="interpreters that plan and verify, in turn"
    )
    ap.add_argument(
        "--swarm-options", nargs="+", default=None, metavar="JSON", help="plan with these SwarmOptions, in turn"
    )
    ap.add_argument(
        "--child-method-roadmap",
        nargs="*",
        default=None,
        metavar="PATH",
        help="these interpreters (all, without a path) call the swarm method 'roadmap' (before the rename)",
    )
    ap.add_argument("--keep", default=None, metavar="DIR", help="keep scenarios and plans in DIR")
    args = ap.parse_args()

    import yaml

    from proxplan.planfile import load_scenario
    from proxplan.planner.bounds import certified_bound
    from proxplan.planner.formations import LAYOUTS, random_formation
    from proxplan.planner.sampling.ordering import lower_bound_makespan_s

    pythons = args.child_python
    roadmap = set(pythons if args.child_method_roadmap == [] else (args.child_method_roadmap or []))
    for i, py in enumerate(pythons):
        base_wall, _, base_mb, _, base_cpu = _run([py, "-m", "proxplan.cli", "--help"], 120)
        print(
            f"py {i}: {py}; baseline (interpreter + CLI start): {base_wall:.2f} s wall, {base_cpu:.2f} s CPU, "
            f"{base_mb:.0f} MB"
        )
    option_sets: list[str | None] = list(args.swarm_options or [None])
    for j, opt in enumerate(option_sets):
        print(f"swarm options {j}: {opt or 'defaults, through the CLI'}")
    print(
        f"{'layout':14s} {'N':>4s} {'goals':8s} {'method':10s} {'arm':>3s} {'wall_s':>7s} {'cpu_s':>6s} "
        f"{'makespan':>8s} {'LB_s':>6s} {'ms/LB':>6s} {'cLB_s':>6s} {'ms/cLB':>6s} {'peak_MB':>7s} {'verify':>6s} {'verify_s':>8s}  how"
    )
    tmp_ctx = tempfile.TemporaryDirectory() if args.keep is None else None
    tmp = Path(args.keep) if args.keep else Path(tmp_ctx.name)  # type: ignore[union-attr]
    tmp.mkdir(parents=True, exist_ok=True)
    layouts: list[tuple[str, object]] = [(name, LAYOUTS[name]) for name in args.layout]
    layouts += [
        (f"random-{seed}", lambda n, seed=seed, **kw: random_formation(n, seed=seed))
        for seed in range(args.family_seed, args.family_seed + args.family)
    ]
    for layout, make in layouts:
        for n in args.n:
            for goals in args.assign:
                kw = {"types": args.types.split(",")} if args.types and not layout.startswith("random") else {}
                doc = make(n, **kw)  # type: ignore[operator]
                if goals == "by_type":
                    doc["assign_goals"] = "by_type"
                path = tmp / f"{layout}-{n}-{goals}.yaml"
                path.write_text(yaml.safe_dump(doc, sort_keys=False))
                lb = lower_bound_makespan_s(load_scenario(path))
                # the certified bound (planner/bounds.py), fixed goals only (per vehicle's own goal)
                clb = certified_bound(load_scenario(path)).bound_s if goals == "fixed" else None
                arms = [(m, p, o) for m in args.method for p in enumerate(pythons) for o in enumerate(option_sets)]
                for method, (i, py), (j, opt) in arms:
                    arm = i * len(option_sets) + j
                    out = tmp / f"out-{layout}-{n}-{goals}-{method}-arm{arm}"
                    if opt is not None:
                        cmd = [
                            py,
                            str(Path(__file__).resolve()),
                            "--child",
                            str(path),
                            str(out),
                            method,
                            opt,
                        ]
                    else:
                        cmd = [py, "-m", "proxplan.cli", "plan", str(path), "--out", str(out)]
                        name = "roadmap" if py in roadmap and method == "swarm" else method
                        cmd += ["--method", name, "--seed", "0", "--no-plot", "--json"]
                    wall, code, mb, text, cpu = _run(cmd, args.timeout, args.cpu_cap)
                    ms = ratio = c_ratio = "-"
                    capped = code == -signal.SIGKILL  # killed by either cap
                    verdict, v_wall, how = ("timeout" if capped else f"exit {code}"), "-", ""
                    lb_used = lb
                    if code == 0:
                        doc_out = json.loads(text.strip().splitlines()[-1])
                        m = doc_out["metrics"]
                        lb_used = float(m.get("assignment_lower_bound_s") or lb)
                        makespan = float(m["makespan_s"])
                        ms, ratio = f"{makespan:.2f}", f"{makespan / lb_used:.2f}"
                        c_ratio = f"{makespan / clb:.2f}" if clb else "-"
                        notes = json.loads((out / "plan.json").read_text()).get("notes", [])
                        planned = 1 + sum("planned again" in note for note in notes)
                        how = f"planned {planned}x; {doc_out['method']}: "
                        how += str((m.get("swarm") or {}).get("coordination", ""))[:70]
                        t_v = time.perf_counter()
                        res = subprocess.run(
                            [py, "-m", "proxplan.cli", "verify", str(out / "plan.json")],
                            capture_output=True,
                            cwd=tempfile.gettempdir(),
                        )
                        v_wall = f"{time.perf_counter() - t_v:.1f}"
                        verdict = "PASS" if res.returncode == 0 else "FAIL"
                    elif text.strip():
                        try:
                            how = json.loads(text.strip().splitlines()[-1]).get("message", "")[:80]
                        except json.JSONDecodeError:
                            how = text.strip()[-80:]
                    clb_s = f"{clb:.2f}" if clb else "-"
                    print(
                        f"{layout:14s} {n:4d} {goals:8s} {method:10s} {arm:3d} {wall:7.1f} {cpu:6.1f} {ms:>8s} {lb_used:6.2f} "
                        f"{ratio:>6s} {clb_s:>6s} {c_ratio:>6s} {mb:7.0f} {verdict:>6s} {v_wall:>8s}  {how}",
                        flush=True,
                    )
    if tmp_ctx is not None:
        tmp_ctx.cleanup()
    return 0


if __name__ == "__main__":
    sys.exit(main())
