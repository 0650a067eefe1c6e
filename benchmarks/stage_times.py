"""Where the CPU of one ``proxplan plan`` goes, by stage of the pipeline and the swarm layer, in this
process (stop 61 round 23A).

Runs the CLI's ``plan`` on a scenario in-process with each function of :data:`STAGES` wrapped by a
timer (CPU: ``time.process_time``; wall: ``time.perf_counter``; inclusive, the outermost call of each
function counted once, so a stage that calls itself, as a level of the stacked plan calls the
swarm layer's ``_plan``, is not counted twice). A wrapper costs a few microseconds per call, not the
several-fold inflation of a tracing profiler on Python-heavy code (cProfile made corridor-64's plan
JSON writing 15 s of CPU; it is 0.4 s). Stages nest (the guard's sub-plans run inside the makespan
repair; the verifier inside the guard and the pipeline), so the shares do not add up to 100 %.

Usage (from outside the repository, so that the interpreter's installed proxplan is imported):
    cd /tmp && PY /path/to/benchmarks/stage_times.py SCENARIO.yaml [--method swarm] [--out DIR]
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import importlib
import io
import json
import os
import sys
import tempfile
import time

_P = "proxplan.planner."
# (module, function or Class.method): the stages timed
STAGES = (
    (_P + "pipeline", "plan_scenario"),
    (_P + "pipeline", "_prepare"),
    (_P + "pipeline", "_swarm_stage"),
    (_P + "pipeline", "_sampling_stage"),
    (_P + "refine_stage", "refine_stage"),
    (_P + "pipeline", "_record"),
    (_P + "swarm.plan", "swarm_timed"),
    (_P + "swarm.problem", "swarm_problem"),
    (_P + "swarm.straight", "straight_step_conflicts"),
    (_P + "swarm.prioritised_stage", "kept_straight_stage"),
    (_P + "swarm.prioritised_stage", "prioritised_stage"),
    (_P + "swarm.components", "plan_groups"),
    ("proxplan.fanout.engine", "fan_out"),
    (_P + "swarm.complete_stages", "lattice_stage"),
    (_P + "swarm.complete_stages", "join_levels"),
    (_P + "swarm.retime_stage", "retime_stage"),
    (_P + "swarm.heights", "heights_pass"),
    (_P + "swarm.repair_stage", "makespan_stage"),
    (_P + "swarm.makespan", "shorten_makespan"),
    (_P + "swarm.verify_guard", "VerifyGuard.__call__"),
    (_P + "swarm.verify_guard", "VerifyGuard.around"),
    # the verifier's parts that the guard's sub-plans and the whole-plan check spend their CPU in (round
    # 30S: corridor-64's 32 sub-plans, 23.5 s, were the loops in the jets and the wrenches along the plan)
    ("proxplan.verify.jet_loop", "loop_along_plan"),
    ("proxplan.verify.along", "wrench_along_plan"),
    ("proxplan.verify.pair_checks", "check_pairs"),
    ("proxplan.verify.pair_checks", "check_authority_tube"),
    ("proxplan.physics.discretize", "zoh_maps"),
    (_P + "swarm.single", "plan_one"),
    (_P + "swarm.retime", "improve"),
    (_P + "swarm.chain", "time_chain"),
    (_P + "swarm.chain", "_time_chain"),
    (_P + "swarm.occupancy", "Occupancy.put"),
    (_P + "swarm.occupancy", "Occupancy.forbidden_departures"),
    (_P + "swarm.occupancy", "Occupancy._departure_index"),
    (_P + "swarm.occupancy", "Occupancy.forbidden_holds"),
    (_P + "swarm.occupancy", "Occupancy.content_key"),
    (_P + "swarm.departures", "DepartureIndex.line_forbidden"),
    (_P + "swarm.departures", "DepartureIndex._line_near"),
    (_P + "swarm.departures", "DepartureIndex.tree_pairs"),
    (_P + "swarm.keepout", "GrownStack.conflict"),
    (_P + "swarm.keepout", "GrownStack.conflict_rz"),
    (_P + "timing.profile", "RunMove.__init__"),
    (_P + "timing.profile", "RunMove.positions"),
    (_P + "timing.profile", "LineMove.positions"),
    (_P + "swarm.lattice", "build_lattice"),
    (_P + "swarm.lacam", "Lacam.solve"),
    (_P + "swarm.lockstep", "lockstep_tracks"),
    ("proxplan.verify.checks", "verify_with_deflections"),
    ("proxplan.verify.checks", "_verified"),
    (_P + "metrics", "finish_metrics"),
    ("proxplan.planfile.plan", "write_plan"),
)


def _wrap(module: str, name: str, table: dict[str, list]) -> None:
    """Time ``module.name`` (a function or ``Class.method``) into ``table[name]`` = [calls, CPU s, wall s],
    replacing every reference to it held by a proxplan module (``from x import f`` included)."""
    mod = importlib.import_module(module)
    parts = name.split(".")
    owner = mod
    for p in parts[:-1]:
        owner = getattr(owner, p)
    orig = getattr(owner, parts[-1])
    rec = table.setdefault(name, [0, 0.0, 0.0])
    depth = [0]

    @functools.wraps(orig)
    def timed(*args, **kwargs):
        if depth[0]:
            return orig(*args, **kwargs)
        depth[0] += 1
        c0, t0 = time.process_time(), time.perf_counter()
        try:
            return orig(*args, **kwargs)
        finally:
            depth[0] -= 1
            rec[0] += 1
            rec[1] += time.process_time() - c0
            rec[2] += time.perf_counter() - t0

    setattr(owner, parts[-1], timed)
    if len(parts) == 1:
        for m in list(sys.modules.values()):
            if m is not None and getattr(m, "__name__", "").startswith("proxplan"):
                for key, value in list(vars(m).items()):
                    if value is orig:
                        setattr(m, key, timed)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenario")
    ap.add_argument("--method", default="swarm")
    ap.add_argument("--out", default=None, help="plan folder (default: a temporary one)")
    args = ap.parse_args()
    c0, t0 = time.process_time(), time.perf_counter()
    table: dict[str, list] = {}
    for module, _ in STAGES:
        importlib.import_module(module)
    imports = (time.process_time() - c0, time.perf_counter() - t0)
    for module, name in STAGES:
        try:
            _wrap(module, name, table)
        except AttributeError:  # not in this version of proxplan
            table[name] = [0, 0.0, 0.0]
    from proxplan.cli import main as cli

    out = args.out or tempfile.mkdtemp(prefix="stage-times-")
    buf = io.StringIO()
    c1, t1 = time.process_time(), time.perf_counter()
    k1 = os.times()
    with contextlib.redirect_stdout(buf):
        cli(["plan", args.scenario, "--out", out, "--method", args.method, "--seed", "0", "--no-plot", "--json"])
    cpu, wall = time.process_time() - c1, time.perf_counter() - t1
    k2 = os.times()
    doc = json.loads(buf.getvalue().strip().splitlines()[-1])
    print(
        f"{args.scenario}: makespan {doc['metrics']['makespan_s']:.3f} s, verify passed {doc['verify']['passed']}; "
        f"plan: CPU {cpu:.1f} s, wall {wall:.1f} s; imports before it: CPU {imports[0]:.1f} s, wall {imports[1]:.1f} s"
    )
    # worker processes (a Dask fan-out's LocalCluster) are not in the process time above: their CPU,
    # and this process's system CPU (a numpy-heavy worker under Dask's malloc trim shows it)
    print(
        f"child processes: user {k2.children_user - k1.children_user:.1f} s, system "
        f"{k2.children_system - k1.children_system:.1f} s; this process's system CPU {k2.system - k1.system:.1f} s"
    )
    print(f"{'stage (function)':32s} {'calls':>6s} {'cpu_s':>7s} {'share':>6s} {'wall_s':>7s}")
    for _, name in STAGES:
        n, c, w = table[name]
        if n:
            print(f"{name:32s} {n:6d} {c:7.2f} {100.0 * c / cpu:5.1f}% {w:7.2f}")
    swarm = doc["metrics"].get("swarm") or {}
    print("makespan repair:", json.dumps(swarm.get("makespan_repair")))
    return 0


if __name__ == "__main__":
    sys.exit(main())
