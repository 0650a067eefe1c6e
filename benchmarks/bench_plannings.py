"""In-process cost of one single-vehicle planning of prioritised planning, and of the departure query.

Runs the first pass of prioritised planning (order "dependencies first", vehicles not planned yet
held 1 s, rest-to-rest moves: the swarm layer's defaults) on a named layout, in this process, for
at most ``--plannings`` single-vehicle plannings, and prints: the number of plannings, their mean
and largest CPU time, the calls and CPU time of ``Occupancy.forbidden_departures``, and a digest of
every planned track (sha256 over the agents and sample positions of each ``plan_one`` result in
order) so that two installed versions can be checked for giving identical plans.

Usage (run from outside the repository so that the interpreter's installed proxplan is imported):
    cd /tmp && PY /path/to/benchmarks/bench_plannings.py --layout corridor --n 64 --plannings 60 [--profile 25]

``--profile K`` prints cProfile's top functions by cumulative time instead (the timing wrappers off).
CPU times are process CPU (``time.process_time``): compare them as ratios against another
interpreter run under the same load.
"""

from __future__ import annotations

import argparse
import cProfile
import hashlib
import pstats
import sys
import time


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--layout", default="corridor")
    ap.add_argument("--n", type=int, default=64)
    ap.add_argument("--plannings", type=int, default=60, help="stop the pass after this many plannings")
    ap.add_argument("--profile", type=int, default=0, help="print this many cProfile rows instead")
    args = ap.parse_args()

    import numpy as np

    import proxplan
    from proxplan.planfile.scenario_load import scenario_from_dict
    from proxplan.planner.formations import LAYOUTS
    from proxplan.planner.sampling.ordering import lower_bound_makespan_s
    from proxplan.planner.swarm import occupancy, priority
    from proxplan.planner.swarm.prioritised_stage import horizon_steps
    from proxplan.planner.swarm.priority_options import PrioritizedFailed, PriorityOptions
    from proxplan.planner.swarm.priority_order import dependency_order
    from proxplan.planner.swarm.problem import swarm_problem

    print(f"proxplan from {proxplan.__file__}")
    scenario = scenario_from_dict(LAYOUTS[args.layout](args.n))
    problem = swarm_problem(scenario)
    horizon = horizon_steps(lower_bound_makespan_s(scenario))
    options = PriorityOptions(max_repairs=10**6, max_plannings=args.plannings, hold_s=1.0, through=False)

    digest = hashlib.sha256()
    per_planning: list[float] = []
    query = {"calls": 0, "cpu_s": 0.0}
    plan_one = priority.plan_one
    forbidden = occupancy.Occupancy.forbidden_departures

    def timed_plan_one(occ, agent, through):
        t0 = time.process_time()
        track = plan_one(occ, agent, through)
        per_planning.append(time.process_time() - t0)
        digest.update(str(agent).encode())
        if track is not None:
            digest.update(np.ascontiguousarray(track.positions_m).tobytes())
        return track

    def timed_forbidden(self, *a, **kw):
        t0 = time.process_time()
        out = forbidden(self, *a, **kw)
        query["calls"] += 1
        query["cpu_s"] += time.process_time() - t0
        return out

    def run() -> str:
        try:
            result = priority.prioritized_tracks(problem, dependency_order(problem), options, horizon_steps=horizon)
            return f"a plan ({result.planned} plannings)"
        except PrioritizedFailed as err:
            return f"gave up after {err.planned} plannings ({err.history[-1] if err.history else ''})"

    if args.profile:
        prof = cProfile.Profile()
        t0 = time.process_time()
        prof.enable()
        how = run()
        prof.disable()
        print(f"{args.layout}-{args.n}: {how}; {time.process_time() - t0:.1f} s CPU under the profiler")
        pstats.Stats(prof).sort_stats("cumulative").print_stats(args.profile)
        return 0
    priority.plan_one = timed_plan_one
    occupancy.Occupancy.forbidden_departures = timed_forbidden
    t0 = time.process_time()
    how = run()
    total = time.process_time() - t0
    n = len(per_planning)
    print(
        f"{args.layout}-{args.n}: {how}; {total:.1f} s CPU; {n} plan_one calls, mean {sum(per_planning) / max(1, n):.3f} s, "
        f"max {max(per_planning, default=0.0):.3f} s; forbidden_departures {query['calls']} calls, "
        f"{query['cpu_s']:.1f} s CPU; tracks digest {digest.hexdigest()[:16]}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
