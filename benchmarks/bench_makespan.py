"""Where a swarm plan's makespan comes from: each vehicle's arrival split into the time it waits at
its start, the time it waits on the way and the time it moves, against its straight line alone
(rest to rest at its own limits, the lower bound's term), and when and how far from its straight
line it passes the half-way plane (the plane through the midpoint of its start and goal, normal
to the line): a queue shows as late crossings, a detour as a large offset.

Runs ``swarm_timed`` in this process with the options the pipeline uses for fixed goals (reserved
starts on, makespan repair off; one worker), as ``bench_swarm_layer.py`` does, and prints the
stages' counts, the CPU time, the mean split over every vehicle and over the latest quarter, and
the latest vehicles one by one.

Usage (run from outside the repository so that the interpreter's installed proxplan is imported):
    cd /tmp && PY /path/to/benchmarks/bench_makespan.py --layout pillar --n 64 [--last 12]

CPU times are process CPU: compare them as ratios against another interpreter run under the same load.
"""

from __future__ import annotations

import argparse
import sys
import time


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--layout", default="pillar")
    ap.add_argument("--n", type=int, default=64)
    ap.add_argument("--last", type=int, default=12, help="latest vehicles printed one by one")
    args = ap.parse_args()

    import numpy as np

    import proxplan
    from proxplan.planfile.scenario_load import scenario_from_dict
    from proxplan.planner.formations import LAYOUTS
    from proxplan.planner.sampling.ordering import lower_bound_makespan_s
    from proxplan.planner.swarm import SwarmOptions, swarm_problem, swarm_timed
    from proxplan.planner.swarm.tracks import GRID_DT_S
    from proxplan.planner.timing.profile import rest_to_rest

    print(f"proxplan from {proxplan.__file__}")
    scenario = scenario_from_dict(LAYOUTS[args.layout](args.n))
    problem = swarm_problem(scenario, tracking_bound=False)  # starts, goals and limits only
    lower_bound = lower_bound_makespan_s(scenario)
    t0 = time.process_time()
    timed, info = swarm_timed(scenario, SwarmOptions(workers=1, reserve_starts=True, makespan_repair=False))
    cpu = time.process_time() - t0
    print(
        f"{args.layout}-{args.n}: {info.stage}, {info.makespan_s:.2f} s = {info.makespan_s / lower_bound:.3f}x the "
        f"bound ({lower_bound:.2f} s); before re-timing {info.initial_makespan_s:.2f} s; {cpu:.1f} s CPU"
    )
    print(f"  {info.coordination}")
    if info.retiming is not None:
        print(f"  re-timing: {info.retiming.passes} passes, makespan after each {info.retiming.makespan_after_pass_s}")

    rows = []
    for a, name in enumerate(problem.names):
        path = timed[name]
        t, segs = np.asarray(path.knot_t_s), path.segments
        moving = sum(float(t[i + 1] - t[i]) for i, s in enumerate(segs) if s is not None)
        start_wait = float(t[1] - t[0]) if segs and segs[0] is None else 0.0
        arrival = float(t[-1])
        s, g = problem.starts_m[a], problem.goals_m[a]
        length = float(np.linalg.norm(g - s))
        alone = rest_to_rest(length, problem.limits[a], GRID_DT_S).steps * GRID_DT_S
        cross_s, offset_m = float("nan"), float("nan")
        if length > 0.0:
            ts = np.arange(0.0, arrival + GRID_DT_S, GRID_DT_S)
            p = path.sample(ts)[0]
            u = (g - s) / length
            along = (p - s) @ u
            k = int(np.argmax(along >= 0.5 * length))
            cross_s = float(ts[k])
            off = p[k] - s - along[k] * u
            offset_m = float(np.linalg.norm(off[:2]))
        n_moves = sum(1 for x in segs if x is not None)
        rows.append(
            (arrival, name, alone, start_wait, arrival - start_wait - moving, moving, n_moves, cross_s, offset_m)
        )
    rows.sort(key=lambda r: (-r[0], r[1]))
    split = np.array([r[2:6] for r in rows])
    quarter = max(1, len(rows) // 4)
    for label, part in (("every vehicle", split), (f"latest {quarter}", split[:quarter])):
        m = part.mean(axis=0)
        print(
            f"  mean over {label}: alone {m[0]:.2f} s, waiting at the start {m[1]:.2f} s, "
            f"waiting on the way {m[2]:.2f} s, moving {m[3]:.2f} s"
        )
    print("  arrival  vehicle  alone  start-wait  way-wait  moving  moves  half-way at  off the line")
    for r in rows[: args.last]:
        print(
            f"  {r[0]:7.2f}  {r[1]:7s}  {r[2]:5.2f}  {r[3]:10.2f}  {r[4]:8.2f}  {r[5]:6.2f}  {r[6]:5d}  "
            f"{r[7]:9.2f} s  {r[8]:9.2f} m"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
