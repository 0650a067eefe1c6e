"""Why the swarm layer gives no plan on a layout (issue 37, round 19C): frozen pairs and where LaCAM stops.

For a named layout or a member of the bench's randomised family, in this process:

* the pairs frozen at the starts and at the goals (:func:`proxplan.planner.swarm.frozen.frozen_pairs`:
  clear of the keep-out at rest, inside it once either vehicle moves), with their horizontal distance,
  height difference and the keep-out's column radius at rest and moving at that height;
* LaCAM on the lattice of the problem as it is (no unfreeze) with the pipeline's budget: how many proposals
  failed, the configuration with the most vehicles at their goal, and for each vehicle not there every
  move it has and the vehicles (staying put) each move conflicts with;
* the same on the unfreezed problem (:func:`proxplan.planner.swarm.frozen.unfrozen_problem`).

Usage (from outside the repository, so that the interpreter's installed proxplan is imported):
    cd /tmp && PY /path/to/benchmarks/why_frozen.py --layout random-3 --n 64
"""

from __future__ import annotations

import argparse
import sys
import time
from collections import Counter


def _column_radius(ko, dz: float, rest: bool) -> float:
    from proxplan.planner.swarm.sync import _column_radius as radius

    return radius(ko, dz, rest)


def _lacam(problem, opts, label: str) -> None:
    from proxplan.planner.errors import PlanNotFound
    from proxplan.planner.swarm.lacam import Lacam
    from proxplan.planner.swarm.lattice import build_lattice
    from proxplan.planner.swarm.sync import SyncTable

    lat = build_lattice(problem, max_run=opts.max_run)
    sync = SyncTable(problem.keepouts, problem.type_index, lat.pos_mm)
    lacam = Lacam(lat, sync, seed=opts.seed)
    best: list = [None, -1]
    told: Counter = Counter()
    generate = lacam._generate

    def counted(node, constraint):
        got = generate(node, constraint)
        told["proposals that failed" if got is None else "proposals"] += 1
        if got is not None:
            at = sum(1 for i in range(problem.n_agents) if got[i] == lacam.goal[i])
            if at > best[1]:
                best[:] = [got, at]
        return got

    lacam._generate = counted  # type: ignore[method-assign]  # this script's instrumentation only
    t0 = time.process_time()
    try:
        res = lacam.solve(max_nodes=opts.max_nodes, max_proposals=opts.max_proposals)
        print(f"{label}: LaCAM found {len(res.configurations) - 1} steps ({res.nodes} configurations)")
        return
    except PlanNotFound as err:
        print(f"{label}: LaCAM {err.message}; {dict(told)}; {time.process_time() - t0:.1f} s CPU")
    cfg = best[0]
    print(f"  most vehicles at their goal: {best[1]} of {problem.n_agents}; the others:")
    names = problem.names
    for i in range(problem.n_agents):
        if cfg[i] == lacam.goal[i]:
            continue
        u = cfg[i]
        at_start = "at its start" if u == int(lat.start_v[i]) else "on the way"
        print(
            f"    {names[i]} ({problem.vehicles[problem.type_index[i]].name}) {at_start}, {lat.dist_to_goal[i][u]:.2f} m to go:"
        )
        for v in lat.moves(i, u):
            hit = [names[j] for j in range(problem.n_agents) if j != i and sync.conflict(i, u, v, j, cfg[j], cfg[j])]
            print(
                f"      move of {lat.dist_to_goal[i][u] - lat.dist_to_goal[i][v]:+.2f} m closer: conflicts with {hit}"
            )


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--layout", default="random-3", help="a named layout, or random-K (family seed K)")
    ap.add_argument("--n", type=int, default=64)
    args = ap.parse_args()

    import numpy as np

    import proxplan
    from proxplan.planfile.scenario_load import scenario_from_dict
    from proxplan.planner.formations import LAYOUTS, random_formation
    from proxplan.planner.swarm import SwarmOptions
    from proxplan.planner.swarm.frozen import frozen_pairs, unfrozen_problem
    from proxplan.planner.swarm.problem import swarm_problem

    print(f"proxplan from {proxplan.__file__}")
    if args.layout.startswith("random-"):
        doc = random_formation(args.n, seed=int(args.layout.split("-")[1]))
    else:
        doc = LAYOUTS[args.layout](args.n)
    problem = swarm_problem(scenario_from_dict(doc))
    print(f"{args.layout}-{args.n}: {doc.get('description', '')}")
    for label, pts in (("starts", problem.starts_m), ("goals", problem.goals_m)):
        pairs = frozen_pairs(problem, pts)
        print(f"frozen pairs at the {label}: {len(pairs)}")
        for a, b in pairs:
            ko = problem.keepouts[(int(problem.type_index[a]), int(problem.type_index[b]))]
            d = pts[b] - pts[a]
            rest, move = (_column_radius(ko, float(d[2]), r) for r in (True, False))
            print(
                f"  {problem.names[a]}-{problem.names[b]}: {float(np.hypot(d[0], d[1])):.3f} m apart horizontally at "
                f"dz {d[2]:+.3f} m; column radius at rest {rest:.3f} m, moving {move:.3f} m"
            )
    opts = SwarmOptions()
    _lacam(problem, opts, "as it is")
    unfrozen, unfreezes, note = unfrozen_problem(problem)
    if unfreezes:
        print(note)
        _lacam(unfrozen, opts, "unfrozen")
    return 0


if __name__ == "__main__":
    sys.exit(main())
