"""Benchmark: loading a large scenario (``proxplan.planfile.load_scenario``): YAML parse plus validation
into the Scenario dataclasses, median of repeated loads in one process (the first load, which builds
lazily-built validators, is reported apart).

Run:  python -m proxplan.planner.formations 1000 --out /tmp/f1000.yaml
      python benchmarks/bench_scenario_load.py /tmp/f1000.yaml [--repeat 7]
To compare two versions, run this script with each version's interpreter in the same session (e.g. the
main checkout's and a branch's virtualenv), alternating, and compare the ratio of the medians.
"""

from __future__ import annotations

import argparse
import statistics
import time

from proxplan.fileio import read_yaml
from proxplan.planfile import load_scenario, scenario_from_dict


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenario", help="scenario YAML file")
    parser.add_argument("--repeat", type=int, default=7, help="timed loads after the first")
    args = parser.parse_args()

    t0 = time.perf_counter()
    sc = load_scenario(args.scenario)
    first_s = time.perf_counter() - t0
    load, parse, build = [], [], []
    for _ in range(args.repeat):
        t0 = time.perf_counter()
        load_scenario(args.scenario)
        load.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        doc = read_yaml(args.scenario, what="scenario file")
        parse.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        scenario_from_dict(doc, source_path=args.scenario)
        build.append(time.perf_counter() - t0)
    print(f"scenario {args.scenario}: {len(sc.vehicles)} vehicles")
    print(f"first load_scenario   {first_s * 1e3:8.1f} ms")
    print(f"load_scenario median  {statistics.median(load) * 1e3:8.1f} ms  (of {args.repeat})")
    print(f"  YAML parse median   {statistics.median(parse) * 1e3:8.1f} ms")
    print(f"  validate + build    {statistics.median(build) * 1e3:8.1f} ms")


if __name__ == "__main__":
    main()
