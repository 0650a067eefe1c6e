"""In-process CPU of the swarm layer, or of its prioritised stage alone, with fixed goals, and a digest
of the plan, so that two installed versions can be compared for cost and for giving the same plan.

Runs ``swarm_timed`` (``--part layer``), ``swarm.prioritised_stage.prioritised_stage`` (``--part prioritised``) or
the joint coordination alone, LaCAM on the lattice then the re-timing of its plan (``--part lattice``,
``_lattice_stage`` and ``_retime_stage``, each timed) on a named layout with the options the pipeline uses for fixed goals (reserved starts on, makespan
repair off; one worker, so the figure is this process's CPU) and prints: the CPU time
(``time.process_time``), what each order of prioritised planning gave, the counts (plannings,
repairs, searches recalled and run where the version reports them), the makespan over the lower
bound and a sha256 digest of every vehicle's timed path (layer) or track samples (prioritised).

Usage (run from outside the repository so that the interpreter's installed proxplan is imported):
    cd /tmp && PY /path/to/benchmarks/bench_swarm_layer.py --layout circle --n 64 [--part prioritised]

CPU times are process CPU: compare them as ratios against another interpreter run under the same load.
"""

from __future__ import annotations

import argparse
import hashlib
import sys
import time


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--layout", default="circle")
    ap.add_argument("--n", type=int, default=64)
    ap.add_argument("--part", choices=("layer", "prioritised", "lattice"), default="layer")
    args = ap.parse_args()

    import numpy as np

    import proxplan
    from proxplan.planfile.scenario_load import scenario_from_dict
    from proxplan.planner.formations import LAYOUTS
    from proxplan.planner.sampling.ordering import lower_bound_makespan_s
    from proxplan.planner.swarm import SwarmOptions, swarm_problem, swarm_timed
    from proxplan.planner.swarm.complete_stages import lattice_stage as _lattice_stage
    from proxplan.planner.swarm.plan import _retime_stage
    from proxplan.planner.swarm.prioritised_stage import prioritised_stage

    print(f"proxplan from {proxplan.__file__}")
    scenario = scenario_from_dict(LAYOUTS[args.layout](args.n))
    options = SwarmOptions(workers=1, reserve_starts=True, makespan_repair=False)
    lower_bound = lower_bound_makespan_s(scenario)
    digest = hashlib.sha256()
    name = f"{args.layout}-{args.n} {args.part}"
    t0 = time.process_time()
    if args.part == "layer":
        timed, info = swarm_timed(scenario, options)
        cpu = time.process_time() - t0
        for v in sorted(timed):
            digest.update(np.ascontiguousarray(timed[v].knot_t_s).tobytes())
            digest.update(np.ascontiguousarray(timed[v].knot_p_m).tobytes())
        how = f"{info.stage}, {info.makespan_s / lower_bound:.3f}x the bound"
        tried, counts = info.prioritised, info.counts
    elif args.part == "lattice":
        extra: dict = {}
        problem = swarm_problem(scenario)
        t0 = time.process_time()  # the stage alone (the problem and its tracking bound apart)
        found = _lattice_stage(problem, options, extra, progress=None, deadline=None)
        t_lacam = time.process_time() - t0
        initial = max(tr.arrival_s for tr in found.tracks)
        by_agent, retiming = _retime_stage(problem, found, initial, options, progress=None, deadline=None)
        cpu = time.process_time() - t0
        for a in sorted(by_agent):
            digest.update(np.ascontiguousarray(by_agent[a].positions_m).tobytes())
        final = max(tr.arrival_s for tr in by_agent.values())
        how = (
            f"LaCAM {t_lacam:.1f} s CPU ({extra['lattice'].steps} steps, {extra['lattice'].nodes} configurations, "
            f"{extra['lattice'].tests} exact tests), lock-step {initial / lower_bound:.3f}x, re-timed "
            f"{final / lower_bound:.3f}x in {cpu - t_lacam:.1f} s CPU ({retiming.passes} passes)"
        )
        tried, counts = None, None
    else:
        extra = {}
        problem = swarm_problem(scenario)
        t0 = time.process_time()  # the stage alone (the problem and its tracking bound apart)
        found = prioritised_stage(problem, lower_bound, options, extra, progress=None, deadline=None)
        cpu = time.process_time() - t0
        if found is not None:
            for tr in found.tracks:
                digest.update(np.ascontiguousarray(tr.positions_m).tobytes())
        how = "gave up" if found is None else f"a plan, {max(tr.arrival_s for tr in found.tracks) / lower_bound:.3f}x"
        tried, counts = extra.get("prioritised"), extra.get("counts")
    print(f"{name}: {how}; {cpu:.1f} s CPU; digest {digest.hexdigest()[:12]}; counts {counts}")
    print(f"  orders: {tried}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
