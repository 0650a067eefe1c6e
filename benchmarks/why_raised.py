"""Where the raised routes of a stacked plan's level spend their CPU and what they buy (issue 37, round 30A).

One level of the stacked plan of a named layout (``--level K``, bottom first) planned alone by the
prioritised stage with the level options (as ``why_128.py --level``), ``--options`` JSON changing the
``SwarmOptions`` (e.g. ``'{"raised_routes": false}'``). Printed: what each pass did (the flat arm, then the
raised arm, :func:`proxplan.planner.swarm.prioritised_stage.prioritised_stage`), the CPU of the stage, and
of the raised plannings (:func:`proxplan.planner.swarm.raised.raised_or`, wrapped for counting only): how
many, their CPU against the flat plannings' (``single.plan_one``), how many gave an earlier arrival, how
many had no flat track, and the flat tracks' delays over the vehicle's unobstructed time (grid steps).

    cd /tmp && PY /path/to/benchmarks/why_raised.py --layout corridor --n 128 --level 1
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace

import numpy as np

# delay bins of the flat tracks over the unobstructed time, grid steps (upper edges)
DELAY_BINS = (0, 10, 20, 40, 80)


def level_problem(layout: str, n: int, k: int):
    """(level ``k``'s subproblem of the stacked plan of the named ``layout`` with ``n`` vehicles, its levels), or
    None where no stack of levels fits (the levels' problems as the swarm layer makes them)."""
    import proxplan.planner.swarm.plan as swarm_plan
    from proxplan.planfile.scenario_load import scenario_from_dict
    from proxplan.planner.formations import LAYOUTS
    from proxplan.planner.swarm import swarm_problem
    from proxplan.planner.swarm.frozen import unfrozen_problem
    from proxplan.planner.swarm.levels import stack_levels
    from proxplan.planner.swarm.stacked import level_subproblem, levelled_endpoints

    scenario = scenario_from_dict(LAYOUTS[layout](n))
    problem, _, _ = unfrozen_problem(swarm_problem(scenario))
    levels = stack_levels(problem, swarm_plan._stacking(scenario, problem)())
    if levels is None:
        return None
    lev_s, lev_g = levelled_endpoints(problem, levels)
    on_levels = replace(problem, starts_m=lev_s, goals_m=lev_g)
    agents = [a for a in range(problem.n_agents) if int(problem.type_index[a]) in levels.groups[k]]
    return level_subproblem(on_levels, agents, levels.band_m(k)), levels


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--layout", default="corridor")
    ap.add_argument("--n", type=int, default=64)
    ap.add_argument("--level", type=int, default=1, help="level K of the stacked plan (bottom first)")
    ap.add_argument("--options", default="{}", help="SwarmOptions changes, JSON")
    args = ap.parse_args()

    import proxplan.planner.swarm.plan as swarm_plan
    import proxplan.planner.swarm.priority as priority
    from proxplan.planner.swarm import SwarmOptions
    from proxplan.planner.swarm.prioritised_stage import prioritised_stage
    from proxplan.planner.swarm.stacked import alone_steps
    from proxplan.planner.swarm.tracks import GRID_DT_S
    from proxplan.planner.timing.profile import rest_to_rest

    got_level = level_problem(args.layout, args.n, args.level)
    if got_level is None:
        print(f"{args.layout}-{args.n}: no stack of levels fits the free box")
        return 0
    sub, levels = got_level
    bound = alone_steps(sub) * GRID_DT_S
    changes = {k: tuple(v) if isinstance(v, list) else v for k, v in json.loads(args.options).items()}
    opts = replace(swarm_plan._level_options(SwarmOptions(workers=1, reserve_starts=True)), **changes)
    band = levels.band_m(args.level)
    print(
        f"{args.layout}-{args.n}, level {args.level} at {levels.heights_m[args.level]:.2f} m (band {band[0]:.2f}-"
        f"{band[1]:.2f} m): {sub.n_agents} vehicles, bound {bound:.2f} s; options {changes}"
    )
    stats: dict = {"calls": 0, "cpu_s": 0.0, "earlier": 0, "no_flat": 0, "flat_cpu_s": 0.0, "delays": []}
    raised_or, plan_one = priority.raised_or, priority.plan_one

    def counted_raised(occ, a, through, track):
        t0 = time.process_time()
        out = raised_or(occ, a, through, track)
        stats["cpu_s"] += time.process_time() - t0
        stats["calls"] += 1
        if track is None:
            stats["no_flat"] += 1
        else:
            p = occ.problem
            alone = rest_to_rest(float(np.linalg.norm(p.goals_m[a] - p.starts_m[a])), p.limits[a], GRID_DT_S).steps
            stats["delays"].append(track.arrival_step - alone)
        stats["earlier"] += out is not track
        return out

    def counted_flat(*a, **kw):
        t0 = time.process_time()
        out = plan_one(*a, **kw)
        stats["flat_cpu_s"] += time.process_time() - t0
        return out

    priority.raised_or, priority.plan_one = counted_raised, counted_flat
    extra: dict = {}
    t0 = time.process_time()
    try:
        got = prioritised_stage(sub, bound, opts, extra, progress=None, deadline=None)
    finally:
        priority.raised_or, priority.plan_one = raised_or, plan_one
    cpu = time.process_time() - t0
    print(f"  {extra['prioritised']}")
    print(f"  {extra['counts']}; {cpu:.1f} s CPU")
    print(f"  plan: {'none' if got is None else f'{max(tr.arrival_s for tr in got.tracks):.2f} s'}")
    edges = (-(10**9), *DELAY_BINS, 10**9)
    hist = [sum(lo < d <= hi for d in stats["delays"]) for lo, hi in zip(edges[:-1], edges[1:])]
    print(
        f"  raised plannings {stats['calls']} ({stats['cpu_s']:.1f} s CPU; flat plannings {stats['flat_cpu_s']:.1f} s),"
        f" {stats['earlier']} earlier, {stats['no_flat']} without a flat track; flat delays (steps) <=0 / 1-10 / "
        f"11-20 / 21-40 / 41-80 / >80: {' / '.join(map(str, hist))}"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
