"""The sampling planner with and without the count budget it gets beside the swarm layer
(``proxplan.planner.pipeline.ALTERNATIVE_SEARCHES_PER_VEHICLE`` searches per vehicle,
``ALTERNATIVE_RRT_ITERATIONS`` RRT iterations per solve), each plan in a fresh process (OMPL seeds
once per process).

Usage:
    python benchmarks/bench_sampling_budget.py [--layout corridor pillar grid circle] [--n 32] [--timeout 400]

Prints per layout and arm: wall and CPU time of the child (s), its outcome (makespan over the lower
bound, or "not found" when the budget was spent, or "timeout"), and the verifier's verdict.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_swarm import _run  # noqa: E402 - the same fresh-process runner

CHILD = """
import json, sys
from proxplan.planfile import load_scenario
from proxplan.planner.errors import PlanNotFound
from proxplan.planner.pipeline import ALTERNATIVE_RRT_ITERATIONS, ALTERNATIVE_SEARCHES_PER_VEHICLE
from proxplan.planner.sampling import SamplingOptions, lower_bound_makespan_s, sampling_plan
from proxplan.planner.timing import moving_end_s
from proxplan.verify import verify_plan
sc = load_scenario(sys.argv[1])
opts = SamplingOptions()
if sys.argv[2] == "budget":
    opts = SamplingOptions(max_searches=ALTERNATIVE_SEARCHES_PER_VEHICLE * len(sc.vehicles),
                           max_iterations=ALTERNATIVE_RRT_ITERATIONS)
try:
    plan = sampling_plan(sc, mode="downwash", seed=0, options=opts, progress=None)
except PlanNotFound as err:
    print(json.dumps({"found": False, "message": err.message})); sys.exit(0)
print(json.dumps({"found": True, "ratio": moving_end_s(plan) / lower_bound_makespan_s(sc),
                  "violations": len(verify_plan(plan, sc))}))
"""


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--layout", nargs="+", default=["corridor", "pillar", "grid", "circle"])
    ap.add_argument("--n", type=int, default=32)
    ap.add_argument("--timeout", type=float, default=400.0)
    args = ap.parse_args()
    import yaml

    from proxplan.planner.formations import LAYOUTS

    tmp = Path(tempfile.mkdtemp())
    print(f"{'layout':9s} {'N':>4s} {'arm':9s} {'wall_s':>7s} {'cpu_s':>6s}  outcome")
    for layout in args.layout:
        path = tmp / f"{layout}-{args.n}.yaml"
        path.write_text(yaml.safe_dump(LAYOUTS[layout](args.n), sort_keys=False))
        for arm in ("unbounded", "budget"):
            wall, code, _, text, cpu = _run([sys.executable, "-c", CHILD, str(path), arm], args.timeout)
            if wall >= args.timeout:
                outcome = "timeout"
            elif code != 0:
                outcome = f"exit {code}"
            else:
                doc = json.loads(text.strip().splitlines()[-1])
                outcome = (
                    f"{doc['ratio']:.2f}x LB, verify {'PASS' if doc['violations'] == 0 else 'FAIL'}"
                    if doc["found"]
                    else f"not found: {doc['message']}"
                )
            print(f"{layout:9s} {args.n:4d} {arm:9s} {wall:7.1f} {cpu:6.1f}  {outcome}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
