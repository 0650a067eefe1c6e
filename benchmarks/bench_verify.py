"""Speed of ``proxplan verify``, the plan's metrics and plan.png at swarm scale (issue 30).

Test plans of N vehicles without any planner: a formation flown on straight, synchronised
rest-to-rest lines (every vehicle leaves at t = 0 and all arrive together, one Ruckig segment each,
:func:`straight_line_plan`). Layouts: ``pillar`` (``proxplan.planner.formations.formation_change``:
two staggered layers swap layers across a pillar, so every path crosses others, the pillar and their
jets: thousands of violations, the stress case), ``expand`` (the same two layers spread to 1.5
times their spacing: nobody crosses, the layers stay stacked; the clean case) and ``shear`` (the
upper layer, 1 m up, slides over the hovering lower one: moving stacks, the plain authority check
passes, so verify runs the tracking-tube check too).

Usage:
    python benchmarks/bench_verify.py [--layout pillar expand shear] [--n 32 64 128 256]
        [--baseline-python PATH] [--baseline-timeout 900] [--checks] [--metrics] [--keep DIR]
    python benchmarks/bench_verify.py --plans PLAN.json [...] [--baseline-python PATH]

With ``--plans PLAN.json ...`` (plan files, or gzipped ones as tests/verify/reference holds) it
times ``proxplan verify PLAN --json`` on those plans instead, each in a fresh process under
``/usr/bin/time -v``: wall, CPU (user + system) and peak memory of this interpreter's and the
baseline's run, one after the other per plan, and whether the verdicts agree to the equivalence
tests' tolerance (kind, vehicle, sample, detail, limit; worst value to ``VALUE_RTOL``).

Per plan it prints the whole-process wall time and peak memory (``resource`` rusage of the child,
MB) of ``proxplan verify plan.json --json`` run by this interpreter, the number of violations and,
with ``--baseline-python`` (an interpreter whose ``proxplan`` is the code to compare with, e.g. a
venv of a worktree at the commit before issue 30's verifier), the same for that one in the same run,
the ratio of the two and whether both found the same violations (kind, vehicle, sample, detail,
worst value to 1e-7). ``--checks`` prints each check's time in-process (the tracking-tube check
forced, though verify skips it when the plain authority check already failed); ``--metrics``
times ``finish_metrics`` and ``plot_plan`` in-process. Wall times on a loaded machine are noisy:
compare the ratios of one run.
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

FINE_DT_S = 0.01  # verify's default grid, s


def straight_line_plan(doc: dict, *, model=None):
    """(scenario, plan) of scenario mapping ``doc`` (with the calibrated ``model``, if any) where
    every vehicle flies one straight rest-to-rest Ruckig segment from its start to its goal (a
    hovering one stays put), all leaving at t = 0 and arriving together (the slowest vehicle's
    minimum time); no planner, no checks."""
    import numpy as np

    from proxplan.planfile import scenario_from_dict
    from proxplan.planner.timing import TimedPath, assemble_plan, min_segment_duration_s, ruckig_segment

    sc = scenario_from_dict(doc, model=model)
    legs = {}
    for name, task in sc.vehicles.items():
        goal = task.goal_m if task.goal_m is not None else task.start_m
        legs[name] = (task.start_m, goal, task.kinematic_limits)
    duration = max(min_segment_duration_s(float(np.linalg.norm(g - s)), lim) for s, g, lim in legs.values())
    timed = {}
    for name, (s, g, lim) in legs.items():
        if float(np.linalg.norm(g - s)) < 1e-9:
            timed[name] = TimedPath(np.array([0.0, duration]), np.array([s, g]), [None])
            continue
        traj = ruckig_segment(s, g, lim, minimum_duration_s=duration)
        timed[name] = TimedPath(np.array([0.0, float(traj.duration)]), np.array([s, g]), [traj])
    return sc, assemble_plan(sc, timed, method="straight-lines", notes=["benchmark: straight synchronised lines"])


def expand(n_vehicles: int) -> dict:
    """The pillar formation's two staggered layers (no pillar) spread to 1.5 times their spacing
    about x = -2 m, each vehicle in its own layer: straight lines that never come closer."""
    from proxplan.planner.formations import formation_change

    doc = formation_change(n_vehicles)
    doc["name"] = f"expand-{n_vehicles}"
    doc["obstacles"] = []
    for v in doc["vehicles"].values():
        x, y, z = v["start"]
        v["goal"] = [round(-2.0 + 1.5 * (x + 2.0), 4), round(1.5 * y, 4), z]
    span = [max(abs(c) for v in doc["vehicles"].values() for c in (v["start"][k], v["goal"][k])) + 1.0 for k in (0, 1)]
    doc["workspace"]["min"][:2] = [-span[0], -span[1]]
    doc["workspace"]["max"][:2] = [span[0], span[1]]
    return doc


def shear(n_vehicles: int) -> dict:
    """The pillar formation's two staggered layers 1 m apart (no pillar, authority limit 0.3): the
    upper layer slides 4.8 m along x over the hovering lower one, every upper vehicle passing over
    several lower ones (stacks that move: the tracking-tube check has work)."""
    from proxplan.planner.formations import formation_change

    doc = formation_change(n_vehicles, layer_gap_m=1.0, authority_fraction=0.3)
    doc["name"] = f"shear-{n_vehicles}"
    doc["obstacles"] = []
    for v in doc["vehicles"].values():
        x, y, z = v["start"]
        v["goal"] = [round(x + 4.8, 4), y, z] if z > 1.5 else [x, y, z]
    doc["workspace"]["max"][0] += 4.8
    return doc


def _layout(name: str, n: int) -> dict:
    from proxplan.planner.formations import LAYOUTS

    return {"expand": expand, "shear": shear}[name](n) if name in ("expand", "shear") else LAYOUTS[name](n)


def _run(cmd: list[str], timeout_s: float) -> tuple[float, int | None, float, str]:
    """Wall time (s), exit code (None: timed out), child peak RSS (MB) and stdout."""
    t0 = time.perf_counter()
    with tempfile.TemporaryFile() as out:
        # run outside the repository: from its root, ``import proxplan`` would find the checkout's
        # own folder first and a baseline interpreter would run this checkout's code
        proc = subprocess.Popen(cmd, stdout=out, stderr=subprocess.DEVNULL, cwd=tempfile.gettempdir())
        timed_out = False
        while True:
            pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                break
            if time.perf_counter() - t0 > timeout_s:
                proc.kill()
                pid, status, usage = os.wait4(proc.pid, 0)
                timed_out = True
                break
            time.sleep(0.05)
        wall = time.perf_counter() - t0
        out.seek(0)
        text = out.read().decode(errors="replace")
    code = None if timed_out else os.waitstatus_to_exitcode(status)
    return wall, code, usage.ru_maxrss / 1024.0, text


def _verify(python: str, plan_json: Path, timeout_s: float) -> dict:
    wall, code, rss, text = _run([python, "-m", "proxplan.cli", "verify", str(plan_json), "--json"], timeout_s)
    out = {"wall_s": wall, "rss_mb": rss, "code": code, "violations": None}
    if code in (0, 1):
        out["violations"] = json.loads(text)["violations"]
    return out


def _same(a: list[dict], b: list[dict]) -> bool:
    key = [(v["kind"], v["vehicle"], v["sample"], v["detail"]) for v in a]
    if key != [(v["kind"], v["vehicle"], v["sample"], v["detail"]) for v in b]:
        return False
    return all(abs(x["value"] - y["value"]) <= 1e-7 * max(abs(y["value"]), 1e-2) for x, y in zip(a, b))


VALUE_RTOL = 1e-8  # a worst value's relative tolerance, as tests/verify/test_equivalence.py


def _timed_verify(python: str, plan_json: Path, timeout_s: float) -> dict:
    """``proxplan verify PLAN --json`` by ``python`` under ``/usr/bin/time -v`` in a fresh process:
    wall s, CPU s (user + system), peak RSS MB, exit code, violations."""
    with tempfile.NamedTemporaryFile(suffix=".time") as tf:
        cmd = ["/usr/bin/time", "-v", "-o", tf.name, python, "-m", "proxplan.cli", "verify", str(plan_json), "--json"]
        _, code, _, text = _run(cmd, timeout_s)
        fields = {}
        for line in Path(tf.name).read_text().splitlines():
            key, _, value = line.strip().rpartition(": ")
            fields[key] = value
    h_m_s = [float(x) for x in fields.get("Elapsed (wall clock) time (h:mm:ss or m:ss)", "nan").split(":")]
    wall = sum(x * 60.0**i for i, x in enumerate(reversed(h_m_s)))
    cpu = float(fields.get("User time (seconds)", "nan")) + float(fields.get("System time (seconds)", "nan"))
    rss = float(fields.get("Maximum resident set size (kbytes)", "nan")) / 1024.0
    violations = json.loads(text)["violations"] if code in (0, 1) else None
    return {"wall_s": wall, "cpu_s": cpu, "rss_mb": rss, "code": code, "violations": violations}


def _agree(a: list[dict], b: list[dict]) -> tuple[bool, float]:
    """(same verdicts: kind, vehicle, sample, detail and limit of every violation, worst values
    within VALUE_RTOL (abs 1e-9); the largest relative difference of the worst values)."""
    key = [(v["kind"], v["vehicle"], v["sample"], v["detail"], v["limit"]) for v in a]
    if key != [(v["kind"], v["vehicle"], v["sample"], v["detail"], v["limit"]) for v in b]:
        return False, float("nan")
    rel = [abs(x["value"] - y["value"]) / max(abs(y["value"]), 1e-300) for x, y in zip(a, b)]
    ok = all(abs(x["value"] - y["value"]) <= VALUE_RTOL * abs(y["value"]) + 1e-9 for x, y in zip(a, b))
    return ok, max(rel, default=0.0)


def bench_plans(plans: list[str], baseline: str | None, timeout_s: float) -> int:
    """Before / after on given plan files (module docstring, ``--plans``)."""
    import gzip
    import shutil

    with tempfile.TemporaryDirectory() as tmp:
        for given in plans:
            path = Path(given).resolve()
            if path.suffix == ".gz":  # verify reads plain JSON: unzip to a temporary file
                plain = Path(tmp) / path.name.removesuffix(".gz")
                with gzip.open(path, "rb") as f, plain.open("wb") as g:
                    shutil.copyfileobj(f, g)
                path = plain
            new = _timed_verify(sys.executable, path, timeout_s)
            line = f"{path.name}: wall {new['wall_s']:.2f} s, CPU {new['cpu_s']:.2f} s, peak {new['rss_mb']:.0f} MB"
            line += f", {len(new['violations'] or [])} violations"
            if baseline:
                old = _timed_verify(baseline, path, timeout_s)
                if new["violations"] is None or old["violations"] is None:
                    same, rel = False, float("nan")
                else:
                    same, rel = _agree(new["violations"], old["violations"])
                line += (
                    f"; baseline wall {old['wall_s']:.2f} s, CPU {old['cpu_s']:.2f} s, peak {old['rss_mb']:.0f} MB; "
                    f"ratio (baseline / this) wall {old['wall_s'] / new['wall_s']:.2f}, CPU {old['cpu_s'] / new['cpu_s']:.2f}; "
                    f"same verdicts: {'yes' if same else 'NO'} (worst values differ by {rel:.1e} relative at most)"
                )
            print(line, flush=True)
    return 0


def child_checks(plan_json: str) -> int:
    """Print one JSON line: seconds of each check of verify in this process (the installed code;
    the pair checks without the loops' deflections)."""
    import numpy as np

    from proxplan.planfile import read_plan
    from proxplan.verify import checks, loop_along_plan, scenario_of_plan, wrench_along_plan
    from proxplan.verify.along import plan_samples

    plan = read_plan(plan_json)
    sc = scenario_of_plan(plan)
    t = np.arange(0.0, float(plan.t_s[-1]) + FINE_DT_S / 2, FINE_DT_S)
    out = {}
    t0 = time.perf_counter()
    samples = plan_samples(plan, t)
    along = wrench_along_plan(plan, sc, t_s=t, samples=samples)
    out["wrench"] = round(time.perf_counter() - t0, 3)
    t0 = time.perf_counter()
    loop_along_plan(plan, sc, along, samples=samples)
    out["loops"] = round(time.perf_counter() - t0, 3)
    zero = {n: np.zeros(t.size) for n in plan.vehicles}
    for name, run in (
        ("pairs", lambda: checks.check_pairs(plan, sc, t, samples, zero)),
        ("authority", lambda: checks.check_authority(sc, t, along, plan.t_s)),
        ("authority_tube", lambda: checks.check_authority_tube(plan, sc, t, samples, zero)),
    ):
        t0 = time.perf_counter()
        run()
        out[name] = round(time.perf_counter() - t0, 3)
    print(json.dumps(out))
    return 0


def child_metrics(plan_json: str, png: str) -> int:
    """Print one JSON line: seconds of finish_metrics and plot_plan in this process."""
    from proxplan.planfile import read_plan
    from proxplan.planner import plot_plan
    from proxplan.planner.metrics import finish_metrics
    from proxplan.verify import scenario_of_plan

    plan = read_plan(plan_json)
    sc = scenario_of_plan(plan)
    t0 = time.perf_counter()
    finish_metrics(sc, plan, planning_time_s=0.0)
    t1 = time.perf_counter()
    plot_plan(plan, sc, png)
    t2 = time.perf_counter()
    print(json.dumps({"finish_metrics": round(t1 - t0, 3), "plot": round(t2 - t1, 3)}))
    return 0


def _child(python: str, args: list[str], timeout_s: float) -> str:
    wall, code, _, text = _run([python, str(Path(__file__).resolve()), *args], timeout_s)
    if code != 0:
        return f"(no answer after {wall:.0f} s)" if code is None else f"(exit {code})"
    return text.strip()


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--layout", nargs="+", default=["pillar", "expand", "shear"])
    parser.add_argument("--n", nargs="+", type=int, default=[32, 64, 128, 256])
    parser.add_argument("--baseline-python", help="interpreter whose proxplan is the code to compare with")
    parser.add_argument("--baseline-timeout", type=float, default=900.0, help="seconds per baseline run (default 900)")
    parser.add_argument("--checks", action="store_true", help="also time each check in-process")
    parser.add_argument("--metrics", action="store_true", help="also time finish_metrics and plot_plan in-process")
    parser.add_argument("--keep", help="write the plans here (default: a temporary folder)")
    parser.add_argument("--plans", nargs="+", help="time verify on these plan files (.json or .json.gz) instead")
    parser.add_argument("--child-checks", help=argparse.SUPPRESS)
    parser.add_argument("--child-metrics", nargs=2, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child_checks:
        return child_checks(args.child_checks)
    if args.child_metrics:
        return child_metrics(*args.child_metrics)
    if args.plans:
        return bench_plans(args.plans, args.baseline_python, args.baseline_timeout)

    from proxplan.planfile import write_plan

    me = sys.executable
    base = tempfile.TemporaryDirectory() if args.keep is None else None
    root = Path(args.keep) if args.keep else Path(base.name)  # type: ignore[union-attr]
    _, _, rss0, _ = _run([me, "-c", "import proxplan.verify"], 60.0)
    print(f"interpreter + import proxplan.verify: peak {rss0:.0f} MB")
    for layout in args.layout:
        for n in args.n:
            folder = root / f"{layout}-{n}"
            folder.mkdir(parents=True, exist_ok=True)
            _, plan = straight_line_plan(_layout(layout, n))
            write_plan(plan, folder)
            plan_json = folder / "plan.json"
            head = f"{layout}-{n}: {plan.t_s[-1]:.2f} s plan, {round(plan.t_s[-1] / FINE_DT_S) + 1} samples checked"
            new = _verify(me, plan_json, 3600.0)
            line = f"{head}; verify {new['wall_s']:.1f} s, peak {new['rss_mb']:.0f} MB, "
            line += f"{len(new['violations'] or [])} violations"
            if args.baseline_python:
                old = _verify(args.baseline_python, plan_json, args.baseline_timeout)
                if old["code"] is None:
                    line += f"; baseline no answer after {old['wall_s']:.0f} s (ratio > {old['wall_s'] / new['wall_s']:.1f})"
                else:
                    same = _same(new["violations"] or [], old["violations"] or [])
                    line += (
                        f"; baseline {old['wall_s']:.1f} s, peak {old['rss_mb']:.0f} MB, "
                        f"ratio {old['wall_s'] / new['wall_s']:.1f}, same violations: {'yes' if same else 'NO'}"
                    )
            print(line, flush=True)
            for flag, extra, label in (
                (args.checks, ["--child-checks", str(plan_json)], "checks"),
                (args.metrics, ["--child-metrics", str(plan_json), str(folder / "plan.png")], "metrics + plot"),
            ):
                if flag:
                    print(f"  {label} (s): {_child(me, extra, 3600.0)}", flush=True)
                    if args.baseline_python:
                        timeout = args.baseline_timeout
                        print(f"  {label}, baseline (s): {_child(args.baseline_python, extra, timeout)}", flush=True)
    if base is not None:
        base.cleanup()
    return 0


if __name__ == "__main__":
    sys.exit(main())
