"""Is the single-vehicle search at least as good as the plan it is part of? Each vehicle of a swarm
plan is planned again alone (:func:`proxplan.planner.swarm.priority.plan_one`) against the others'
final tracks; its own track is a witness that a track exists, so a search that is sound and at least
as good as its own plan finds one arriving no later.

Runs ``swarm_timed`` in this process with the options the pipeline uses for fixed goals (as
``bench_makespan.py`` does), keeps the final tracks (after re-timing), and counts, per layout:
no track / a later arrival / the same / an earlier one; per vehicle without a track, whether the
exact timing of its own waypoint chain finds it again (``own chain``) and whether the wavefront
finds a route (``wave``).

Usage (run from outside the repository so that the interpreter's installed proxplan is imported):
    cd /tmp && PY /path/to/benchmarks/bench_replan.py --layout pillar circle grid --n 64 32 64

``--n`` gives one count per layout (or one for all). CPU times are process CPU.
"""

from __future__ import annotations

import argparse
import time


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--layout", nargs="+", default=["pillar"])
    ap.add_argument("--n", nargs="+", type=int, default=[64])
    ap.add_argument("--verbose", action="store_true", help="one line per vehicle not found again")
    ap.add_argument(
        "--heights", action="store_true", help="re-plan with plan_one(heights=True) (the plan itself is unchanged)"
    )
    args = ap.parse_args()
    ns = args.n if len(args.n) == len(args.layout) else [args.n[0]] * len(args.layout)

    import proxplan
    import proxplan.planner.swarm.stages as swarm_stages
    from proxplan.planfile.scenario_load import scenario_from_dict
    from proxplan.planner.formations import LAYOUTS
    from proxplan.planner.swarm import SwarmOptions, swarm_timed
    from proxplan.planner.swarm.chain import time_chain
    from proxplan.planner.swarm.occupancy import Occupancy
    from proxplan.planner.swarm.priority import plan_one
    from proxplan.planner.swarm.retime_stage import HORIZON_MARGIN_S
    from proxplan.planner.swarm.tracks import GRID_DT_S
    from proxplan.planner.swarm.wave import wave_route

    print(f"proxplan from {proxplan.__file__}")
    for layout, n in zip(args.layout, ns):
        got: dict = {}
        stage = swarm_stages.makespan_stage

        def keep(problem, by_agent, opts, *, progress, deadline, _stage=stage, _got=got):
            _got["problem"], _got["tracks"] = problem, dict(by_agent)  # the final tracks, before the repair
            return _stage(problem, by_agent, opts, progress=progress, deadline=deadline)

        swarm_stages.makespan_stage = keep
        # the plan without the second, height-aware prioritised plan (its tail would overwrite the capture)
        options = SwarmOptions(workers=1, reserve_starts=True, makespan_repair=False, heights=False)
        try:
            t0 = time.process_time()
            _, info = swarm_timed(scenario_from_dict(LAYOUTS[layout](n)), options)
            cpu_plan = time.process_time() - t0
        finally:
            swarm_stages.makespan_stage = stage
        problem, tracks = got["problem"], got["tracks"]
        makespan = max(tr.arrival_s for tr in tracks.values())
        horizon = int(round((makespan + HORIZON_MARGIN_S) / GRID_DT_S))
        through = options.through_waypoints == "always"
        occ = Occupancy(problem, list(tracks.values()), horizon)
        counts = {"no track": 0, "later": 0, "same": 0, "earlier": 0}
        lines = []
        t0 = time.process_time()
        for a in sorted(tracks):
            own = occ.remove(a)
            new = plan_one(occ, a, through, heights=args.heights)
            if new is None:
                counts["no track"] += 1
                chain = time_chain(occ, a, own.route_m, through=through) if own.route_m is not None else None
                wave = wave_route(occ, a, problem.starts_m[a], problem.goals_m[a], heights=args.heights)
                lines.append(
                    f"    {problem.names[a]}: own arrival {own.arrival_s:.2f} s, {len(own.moves)} moves; own chain "
                    + ("not found" if chain is None else f"{chain.arrival_step * GRID_DT_S:.2f} s")
                    + f"; wave {'none' if wave is None else f'{len(wave)} waypoints'}"
                )
            elif new.arrival_step > own.arrival_step:
                counts["later"] += 1
            elif new.arrival_step == own.arrival_step:
                counts["same"] += 1
            else:
                counts["earlier"] += 1
            occ.put(own)
        cpu_replan = time.process_time() - t0
        print(
            f"{layout}-{n} ({info.stage}, {makespan:.2f} s before the makespan repair, plan {cpu_plan:.1f} s CPU): "
            + ", ".join(f"{k} {v}" for k, v in counts.items())
            + f" of {len(tracks)} ({cpu_replan:.1f} s CPU)"
        )
        if args.verbose:
            print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
