"""CPU time of ``verify_plan`` on given plan files, this checkout against a baseline interpreter's
``proxplan`` (e.g. the main checkout's), in the same run: each interpreter verifies every plan
``--repeat`` times in a child process (in-process ``time.process_time``, best of the repeats; no
interpreter start-up or imports counted), the two alternating ``--rounds`` times; prints per plan the
best of each and the ratio after / before, and the total.

Run (from a directory where neither checkout is importable by accident, e.g. /tmp):
    python benchmarks/bench_verify_cpu.py --baseline-python PY [--repeat 2] [--rounds 2] PLAN.json ...
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys

CHILD = """
import json, sys, time
from proxplan.planfile import read_plan
from proxplan.verify import scenario_of_plan, verify_plan
out = {}
for path in sys.argv[2:]:
    plan = read_plan(path)
    scenario = scenario_of_plan(plan)
    best = float("inf")
    for _ in range(int(sys.argv[1])):
        t0 = time.process_time()
        verify_plan(plan, scenario)
        best = min(best, time.process_time() - t0)
    out[path] = best
print(json.dumps(out))
"""


def _times(python: str, repeat: int, plans: list[str]) -> dict[str, float]:
    run = subprocess.run([python, "-c", CHILD, str(repeat), *plans], capture_output=True, text=True, check=True)
    return json.loads(run.stdout.strip().splitlines()[-1])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("plans", nargs="+", help="plan.json files")
    ap.add_argument("--baseline-python", required=True, help="interpreter whose proxplan is the code before")
    ap.add_argument("--repeat", type=int, default=2, help="verifications per plan and child (default 2)")
    ap.add_argument("--rounds", type=int, default=2, help="alternating rounds of the two (default 2)")
    args = ap.parse_args()
    before: dict[str, float] = {}
    after: dict[str, float] = {}
    for _ in range(args.rounds):
        for store, python in ((before, args.baseline_python), (after, sys.executable)):
            for path, t in _times(python, args.repeat, args.plans).items():
                store[path] = min(store.get(path, float("inf")), t)
    for path in args.plans:
        print(
            f"{path:<60} before {before[path]:7.3f} s  after {after[path]:7.3f} s  ratio {after[path] / before[path]:5.2f}"
        )
    tb, ta = sum(before.values()), sum(after.values())
    print(f"{'total':<60} before {tb:7.3f} s  after {ta:7.3f} s  ratio {ta / tb:5.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
