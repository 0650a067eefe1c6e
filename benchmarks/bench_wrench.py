"""Benchmark: disturbance model on 100,000 offsets (small-quad over large-quad, default
discretisation), vectorised batch vs a plain per-offset Python loop over the same function.

Run:  python benchmarks/bench_wrench.py [--n 100000] [--loop-n 2000]
The loop is timed on --loop-n offsets and its rate extrapolated; both figures come from this run.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from proxplan.physics import authority_usage, disturbance_wrench
from proxplan.physics.builtin_vehicles import LARGE_QUAD, SMALL_QUAD


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=100_000, help="offsets in the batch")
    parser.add_argument("--loop-n", type=int, default=2_000, help="offsets timed in the loop")
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    offsets = rng.uniform([-1.5, -1.5, -3.0], [1.5, 1.5, -0.3], size=(args.n, 3))
    disturbance_wrench(SMALL_QUAD, LARGE_QUAD, offsets[:10])  # warm caches

    t0 = time.perf_counter()
    batch = disturbance_wrench(SMALL_QUAD, LARGE_QUAD, offsets)
    usage = authority_usage(LARGE_QUAD, batch.force_N, batch.torque_Nm)
    batch_s = time.perf_counter() - t0

    t0 = time.perf_counter()
    for offset in offsets[: args.loop_n]:
        w = disturbance_wrench(SMALL_QUAD, LARGE_QUAD, offset)
        authority_usage(LARGE_QUAD, w.force_N, w.torque_Nm)
    loop_s = time.perf_counter() - t0

    batch_rate = args.n / batch_s
    loop_rate = args.loop_n / loop_s
    print(f"batch: {args.n} offsets (wrench + authority) in {batch_s:.3f} s = {batch_rate:,.0f} offsets/s")
    print(f"loop:  {args.loop_n} offsets one call each in {loop_s:.3f} s = {loop_rate:,.0f} offsets/s")
    print(f"speed-up batch / loop: {batch_rate / loop_rate:.0f}x  (max usage {usage.max():.3f})")


if __name__ == "__main__":
    main()
