"""Where the CPU of one swarm-layer plan goes (issue 37, cause 3): CPU per stage, per part of a
single-vehicle search, and per single-vehicle planning by how many vehicles were planned before it.

Runs ``swarm_timed`` in this process on a named layout with the options the pipeline uses for fixed
goals (reserved starts on; one worker, so every figure is this process's CPU) under cProfile with a
CPU clock (``time.process_time``; the profiler itself adds about a third, so compare shares, not
totals, with other runs) and prints:

* the stages: the cumulative CPU of the functions that run them (a level of the stacked plan runs the
  same functions again: its share is printed apart);
* the single-vehicle search's parts (inclusive CPU of each function, summed over every caller);
* every single-vehicle planning of prioritised planning (``single.plan_one``) binned by the
  vehicles planned before it (tracks with a move in the occupancy): count and mean CPU, per problem
  size (the whole swarm, or a level of the stacked plan).

Usage (run from outside the repository so that the interpreter's installed proxplan is imported):
    cd /tmp && PY /path/to/benchmarks/profile_swarm.py --layout grid --n 128 [--top 25]
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import sys
import time
from collections import defaultdict

# (label, module file suffix, function name): inclusive CPU of each
STAGES = (
    ("whole swarm layer", "swarm/plan.py", "swarm_timed"),
    ("prioritised stage (every call)", "swarm/prioritised_stage.py", "prioritised_stage"),
    ("  collision repair (LNS)", "swarm/lns.py", "remove_collisions"),
    ("lattice plan (LaCAM, every call)", "swarm/complete_stages.py", "lattice_stage"),
    ("stacked plan (its levels' stages)", "swarm/complete_stages.py", "join_levels"),
    ("re-timing (every call)", "swarm/plan.py", "_retime_stage"),
    ("pass with both wavefronts", "swarm/heights.py", "heights_pass"),
    ("makespan repair", "swarm/plan.py", "_makespan_stage"),
    ("straight-step conflicts", "swarm/straight.py", "straight_step_conflicts"),
)
PARTS = (
    ("single-vehicle planning (plan_one)", "swarm/single.py", "plan_one"),
    ("  wavefront route (wave_route, searched)", "swarm/wave.py", "_wave_route"),
    ("    its marks of the others (others_marks)", "swarm/wave_marks.py", "others_marks"),
    ("    marking layers (mark_upto)", "swarm/wave_marks.py", "mark_upto"),
    ("    the front (_spread)", "swarm/wave.py", "_spread"),
    ("  safe-interval timing (_time_chain, searched)", "swarm/chain.py", "_time_chain"),
    ("    departure queries (forbidden_departures)", "swarm/occupancy.py", "forbidden_departures"),
    ("      their pairs (DepartureIndex.pairs)", "swarm/departures.py", "pairs"),
    ("      index builds (_departure_index)", "swarm/occupancy.py", "_departure_index"),
    ("    hold queries (forbidden_holds)", "swarm/occupancy.py", "forbidden_holds"),
    ("  conflicting_agents", "swarm/occupancy.py", "conflicting_agents"),
    ("occupancy put/remove", "swarm/occupancy.py", "put"),
    ("LaCAM solve", "swarm/lacam.py", "solve"),
    ("  its synchronous conflict tests", "swarm/sync.py", "conflict"),
    ("  its pre-test of pairs in reach (maybe_near)", "swarm/sync.py", "maybe_near"),
)
BIN = 16  # planned-before bins of this many vehicles


def _inclusive(stats: pstats.Stats, suffix: str, name: str) -> tuple[float, int]:
    """(inclusive CPU s, primitive calls) of the function ``name`` in a file ending with ``suffix``;
    recursive calls counted once (pstats' cumulative time)."""
    total, calls = 0.0, 0
    for (path, _line, fn), (cc, _nc, _tt, ct, _callers) in stats.stats.items():  # type: ignore[attr-defined]
        if fn == name and path.replace("\\", "/").endswith(suffix):
            total += ct
            calls += cc
    return total, calls


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--layout", default="grid")
    ap.add_argument("--n", type=int, default=128)
    ap.add_argument("--top", type=int, default=0, help="also print the top functions by own CPU")
    args = ap.parse_args()

    import proxplan
    import proxplan.planner.swarm.priority as priority
    from proxplan.planfile.scenario_load import scenario_from_dict
    from proxplan.planner.formations import LAYOUTS
    from proxplan.planner.swarm import SwarmOptions, swarm_timed

    print(f"proxplan from {proxplan.__file__}")
    scenario = scenario_from_dict(LAYOUTS[args.layout](args.n))
    options = SwarmOptions(workers=1, reserve_starts=True)

    # every single-vehicle planning of prioritised planning: (problem size, planned before, CPU s)
    plannings: list[tuple[int, int, float]] = []
    inner = priority.plan_one

    def timed_plan_one(occ, agent, through, *, heights=False):
        before = sum(1 for tr in occ.tracks.values() if tr.moves and tr.agent != agent)
        t = time.process_time()
        try:
            return inner(occ, agent, through, heights=heights)
        finally:
            plannings.append((occ.problem.n_agents, before, time.process_time() - t))

    priority.plan_one = timed_plan_one  # the pass's own plannings (the repair's go through lambdas to it)
    stages: list[tuple[float, str]] = []
    t0 = time.process_time()

    def progress(message: str, fraction: float | None = None) -> None:
        head = "".join(ch for ch in message if not ch.isdigit()).split("(")[0].strip()
        if not stages or stages[-1][1] != head:
            stages.append((time.process_time() - t0, head))

    prof = cProfile.Profile(time.process_time)
    prof.enable()
    timed, info = swarm_timed(scenario, options, progress=progress)
    prof.disable()
    cpu = time.process_time() - t0
    priority.plan_one = inner
    print(
        f"{args.layout}-{args.n}: {info.stage}, makespan {info.makespan_s:.2f} s = "
        f"{info.makespan_s / info.lower_bound_s:.2f}x, {cpu:.1f} s CPU under the profiler"
    )
    print(f"  prioritised: {info.prioritised}")
    print(f"  counts: {info.counts}")
    stats = pstats.Stats(prof)
    print("\nstage (inclusive CPU under the profiler)       CPU s   share  calls")
    for label, suffix, name in STAGES:
        ct, calls = _inclusive(stats, suffix, name)
        print(f"  {label:<44} {ct:7.1f} {100 * ct / cpu:6.1f}%  {calls}")
    print("\npart                                            CPU s   share  calls")
    for label, suffix, name in PARTS:
        ct, calls = _inclusive(stats, suffix, name)
        print(f"  {label:<44} {ct:7.1f} {100 * ct / cpu:6.1f}%  {calls}")
    print("\nprogress (process CPU at the first message of each stage)")
    for t, head in stages:
        print(f"  {t:7.1f} s  {head}")
    print("\nsingle-vehicle plannings of prioritised planning by vehicles planned before (problem size)")
    by: dict[tuple[int, int], list[float]] = defaultdict(list)
    for n, before, c in plannings:
        by[(n, before // BIN)].append(c)
    for n in sorted({k[0] for k in by}, reverse=True):
        rows = [(b, by[(n, b)]) for b in sorted(b for m, b in by if m == n)]
        total = sum(sum(v) for _, v in rows)
        count = sum(len(v) for _, v in rows)
        print(f"  {n} vehicles: {count} plannings, {total:.1f} s CPU")
        for b, v in rows:
            print(
                f"    planned before {b * BIN:4d}-{b * BIN + BIN - 1:<4d} {len(v):5d} x {1000 * sum(v) / len(v):7.1f} ms"
            )
    if args.top:
        print()
        stats.sort_stats("tottime").print_stats(args.top)
    return 0


if __name__ == "__main__":
    sys.exit(main())
