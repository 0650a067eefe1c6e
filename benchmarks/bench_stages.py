"""Where one ``plan_scenario`` call spends its CPU, stage by stage: the process CPU time at the first
progress message of each stage (prioritised planning, the lattice coordination, re-timing, the
sampling planner, ...), then the plan's makespan over the lower bound and its notes.

Usage (run from outside the repository so that the interpreter's installed proxplan is imported):
    cd /tmp && PY /path/to/benchmarks/bench_stages.py --layout corridor --n 64 [--assign by_type]
        [--no-alternative]

The pipeline runs in this process with ``method="swarm"`` (no verification by a second process, no
plan file): compare the CPU times as ratios against another interpreter run under the same load.
"""

from __future__ import annotations

import argparse
import re
import sys
import time


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--layout", default="corridor")
    ap.add_argument("--n", type=int, default=64)
    ap.add_argument("--assign", choices=("fixed", "by_type"), default="fixed")
    ap.add_argument(
        "--no-alternative", action="store_true", help="leave out the sampling planner beside the swarm layer"
    )
    args = ap.parse_args()

    import proxplan
    from proxplan.planfile.scenario_load import scenario_from_dict
    from proxplan.planner.formations import layout_doc
    from proxplan.planner.pipeline import plan_scenario
    from proxplan.planner.sampling.ordering import lower_bound_makespan_s
    from proxplan.planner.timing.plan_grid import moving_end_s

    print(f"proxplan from {proxplan.__file__}")
    scenario = scenario_from_dict(layout_doc(args.layout, args.n, assign=args.assign))
    last: list[str] = [""]
    t0 = time.process_time()

    def progress(message: str, fraction: float | None = None) -> None:
        head = re.sub(r"[0-9]+(/[0-9]+)?|\(.*\)", "", str(message)).strip()  # the stage, not its counters
        if head != last[0]:
            last[0] = head
            print(f"{time.process_time() - t0:8.1f} s CPU  {message}", flush=True)

    plan = plan_scenario(
        scenario, method="swarm", seed=0, progress=progress, sampling_alternative=not args.no_alternative
    )
    makespan = moving_end_s(plan)
    bound = lower_bound_makespan_s(scenario)
    print(
        f"{time.process_time() - t0:8.1f} s CPU  done: {plan.method}, {makespan:.2f} s = {makespan / bound:.2f}x the bound"
    )
    for note in plan.notes:
        print(f"  note: {note}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
