"""CPU time and value of the swarm layer's a-priori tracking bound
(``proxplan.planner.swarm.problem.tracking_growth_m``: one bound per vehicle type and set of limits),
for each given interpreter (other installed versions of proxplan) in the same run, on the bench's
named layouts (``by_type``, as ``bench_swarm.py`` writes them). Each interpreter computes the bound in
a fresh child process (in-process ``time.process_time``, imports and scenario reading not counted),
the interpreters alternating ``--rounds`` times; prints per layout and interpreter the best CPU time
of the rounds, the distinct bounds (m, to the last bit: ``repr``) and whether every interpreter gave
the same bounds.

Run (from a directory where no checkout is importable by accident, e.g. /tmp):
    python benchmarks/bench_tracking_bound.py --child-python PY_BEFORE PY_AFTER [--layout grid circle corridor]
        [--n 64] [--rounds 2]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

CHILD = """
import json, sys, time
from proxplan.planfile import load_scenario
from proxplan.planner.swarm.problem import tracking_growth_m
sc = load_scenario(sys.argv[1])
t0 = time.process_time()
bounds = tracking_growth_m(sc)
cpu = time.process_time() - t0
print(json.dumps({"cpu_s": cpu, "bounds": sorted({repr(b) for b in bounds.values()})}))
"""


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--child-python", nargs="+", required=True, metavar="PY")
    ap.add_argument("--layout", nargs="+", default=["grid", "circle", "corridor"])
    ap.add_argument("--n", type=int, default=64)
    ap.add_argument("--rounds", type=int, default=2)
    args = ap.parse_args(argv)

    import yaml

    from proxplan.planner.formations import layout_doc

    with tempfile.TemporaryDirectory() as tmp:
        for layout in args.layout:
            doc = layout_doc(layout, args.n, assign="by_type")
            path = Path(tmp) / f"{layout}-{args.n}.yaml"
            path.write_text(yaml.safe_dump(doc, sort_keys=False))
            best: dict[int, float] = {}
            values: dict[int, list[str]] = {}
            for _ in range(args.rounds):
                for i, py in enumerate(args.child_python):
                    run = subprocess.run(
                        [py, "-c", CHILD, str(path)], capture_output=True, text=True, check=True, cwd=tmp
                    )
                    out = json.loads(run.stdout.strip().splitlines()[-1])
                    best[i] = min(best.get(i, float("inf")), out["cpu_s"])
                    values[i] = out["bounds"]
            same = all(v == values[0] for v in values.values())
            for i in best:
                ratio = best[i] / best[0]
                print(
                    f"{layout}-{args.n} py {i}: {best[i]:.2f} s CPU ({ratio:.2f}x py 0); bounds m {', '.join(values[i])}",
                    flush=True,
                )
            print(f"{layout}-{args.n}: same bounds: {'yes' if same else 'NO'}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
