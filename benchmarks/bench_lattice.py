"""The lattice plan (the swarm layer's fallback) on a named layout for several longest runs
(``SwarmOptions.max_run``): what the coordination search gives and what bounds it.

For each ``--max-run`` value, in this process: LaCAM on the lattice (the swarm layer's budgets),
its steps and configurations, its CPU time, the makespan over the lower bound
(``lower_bound_makespan_s``: the longest single-vehicle straight flight) of the plan flown in
lock-step and in dependency order (``lockstep_tracks``, ``dependencies``), and the *alone bound*: the
largest over vehicles of its least time from start to goal over the lattice's moves, alone, rest to
rest at every vertex at its own limits (Dijkstra over ``Lattice.moves``). A lock-step step lasts at
least each of its moves' rest-to-rest time, so no lock-step plan of that lattice arrives earlier;
the gap between it and the plan is the coordination's cost (waiting and shuffling), not the hops'.
With ``--layer`` also the whole swarm layer (``swarm_timed``, the pipeline's fixed-goal options,
this ``max_run``), its makespan over the bound, its CPU time and the verifier's verdict.

Usage (run from outside the repository so that the interpreter's installed proxplan is imported):
    cd /tmp && PY /path/to/benchmarks/bench_lattice.py --layout grid --n 64 --max-run 4 8 [--layer]

CPU times are process CPU (``time.process_time``): compare them as ratios within one run.
"""

from __future__ import annotations

import argparse
import sys
import time


def alone_bound_s(lattice) -> float:
    """The alone bound of ``lattice`` (see module), s."""
    import numpy as np
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import dijkstra

    from proxplan.planner.swarm.tracks import GRID_DT_S
    from proxplan.planner.timing.profile import rest_to_rest

    problem = lattice.problem
    V = lattice.pos_m.shape[0]
    worst = 0.0
    seconds: dict[tuple, float] = {}
    for a in range(problem.n_agents):
        lim = problem.limits[a]
        rows, cols, wts = [], [], []
        for v in range(V):
            for w in lattice.moves(a, v):
                key = (round(float(np.linalg.norm(lattice.pos_m[w] - lattice.pos_m[v])), 6), lim)
                if key not in seconds:
                    seconds[key] = rest_to_rest(key[0], lim, GRID_DT_S).duration_s
                rows.append(v)
                cols.append(w)
                wts.append(seconds[key])
        graph = csr_matrix((np.asarray(wts), (np.asarray(rows), np.asarray(cols))), shape=(V, V))
        t = float(dijkstra(graph, directed=True, indices=int(lattice.start_v[a]))[int(lattice.goal_v[a])])
        worst = max(worst, t)
    return worst


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--layout", default="grid")
    ap.add_argument("--n", type=int, default=64)
    ap.add_argument("--max-run", type=int, nargs="+", default=[4, 8])
    ap.add_argument("--layer", action="store_true", help="also run the whole swarm layer and verify its plan")
    args = ap.parse_args()

    import proxplan
    from proxplan.planfile.scenario_load import scenario_from_dict
    from proxplan.planner.formations import LAYOUTS
    from proxplan.planner.sampling.ordering import lower_bound_makespan_s
    from proxplan.planner.swarm import Lacam, SwarmOptions, SyncTable, build_lattice, swarm_problem, swarm_timed
    from proxplan.planner.swarm.lockstep import lockstep_tracks
    from proxplan.planner.timing import assemble_plan
    from proxplan.verify import verify_plan

    print(f"proxplan from {proxplan.__file__}")
    scenario = scenario_from_dict(LAYOUTS[args.layout](args.n))
    problem = swarm_problem(scenario)
    lb = lower_bound_makespan_s(scenario)
    for run in args.max_run:
        opts = SwarmOptions(workers=1, reserve_starts=True, makespan_repair=False, max_run=run)
        lattice = build_lattice(problem, max_run=run)
        sync = SyncTable(problem.keepouts, problem.type_index, lattice.pos_mm)
        t0 = time.process_time()
        res = Lacam(lattice, sync, seed=opts.seed).solve(max_nodes=opts.max_nodes, max_proposals=opts.max_proposals)
        cpu = time.process_time() - t0
        lock = max(tr.arrival_s for tr in lockstep_tracks(lattice, res.configurations, dependencies=False))
        t0 = time.process_time()
        dep = max(tr.arrival_s for tr in lockstep_tracks(lattice, res.configurations))
        dep_cpu = time.process_time() - t0
        alone = alone_bound_s(lattice)
        print(
            f"{args.layout}-{args.n} max_run {run}: {len(res.configurations) - 1} steps, {res.nodes} configurations, "
            f"LaCAM {cpu:.1f} s CPU; lock-step {lock / lb:.3f}x the bound, dependency order {dep / lb:.3f}x "
            f"({dep_cpu:.2f} s CPU); alone bound {alone / lb:.3f}x",
            flush=True,
        )
        if args.layer:
            t0 = time.process_time()
            timed, info = swarm_timed(scenario, opts)
            cpu = time.process_time() - t0
            errors = verify_plan(assemble_plan(scenario, timed, method="swarm", notes=[]), scenario)
            print(
                f"  swarm layer: {info.stage}, {info.makespan_s / lb:.3f}x the bound, {cpu:.1f} s CPU; "
                f"verify: {'passed' if not errors else errors[0]}",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
