"""Why prioritised planning of the whole swarm gives up on a named layout, and what a repair could give
(issue 37, round 29A; docs/planner.md, "Stop 67, round 29A").

For ``--layout`` at ``--n`` vehicles with fixed goals, in-process (the swarm layer's default options,
reserved starts on as with fixed goals through the pipeline):

1. the whole swarm's prioritised stage (``prioritised_stage``, every order and hold it tries), each pass
   recorded (``why_128_common``): plannings, CPU s, the vehicles that failed and how, the last line;
   for each pass that gave up on the in-collision cap, the DISTINCT vehicles still flying in collision
   against the entries the cap counted (a vehicle that goes round in a circle again is counted again);
2. the geometry behind it: ordered pairs (a, b) whose start and goal both lie on the other's route
   flown alone (``why_128_one_pass.cycle_pairs``: b must leave before a passes and arrive after a
   passed: a overtakes b on one line), and the vehicles that failed most, with their ends;
3. with ``--complete``: the same passes with no in-collision cap and the collision repair
   (``swarm.lns``) given ``--lns`` plannings per vehicle: the makespan of the completed pass before its
   collisions are removed and after the repair, and the colliding pairs left (an indication of what a
   repair of the pass could give, not a bound: a neighbourhood planned again may arrive earlier).

    cd /tmp && python /path/to/benchmarks/why_gives_up.py --layout corridor --n 64 [--complete --lns 1]
"""

from __future__ import annotations

import argparse
import re
import sys
import time
from collections import Counter
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from why_128_common import _passes_recorder, _print_pass  # noqa: E402
from why_128_one_pass import cycle_pairs  # noqa: E402

# a vehicle's name at the start of a line of a pass's history ("v012: why" for a vehicle that failed)
FAILED = re.compile(r"^(v\d+): ")


def _complete_passes(priority, lns_per_vehicle: int, lower_bound_s: float) -> tuple:
    """Patch ``priority`` so that passes run with no in-collision cap, the collision repair with
    ``lns_per_vehicle`` plannings per vehicle, and print each pass's makespan before and after it;
    returns what was patched (``_restore`` puts it back)."""
    from proxplan.planner.swarm.lns import colliding_pairs

    inner_pass, inner_repair = priority._in_order, priority._remove_collisions
    saved = (inner_pass, inner_repair, priority.LNS_PLANNINGS_PER_VEHICLE)
    priority.LNS_PLANNINGS_PER_VEHICLE = lns_per_vehicle

    def uncapped(problem, order, options, **kw):
        return inner_pass(problem, order, replace(options, max_in_collision=None), **kw)

    def measured(occ, planned, stuck, options, result, deadline, res=None):
        arrival = max(tr.arrival_s for tr in planned.values())
        names = [occ.problem.names[a] for a in stuck]
        print(
            f"  completed pass, hold {options.hold_s:g} s: {arrival:.2f} s ({arrival / lower_bound_s:.2f}x) before "
            f"its collisions are removed; {len(names)} in collision {names}, {len(colliding_pairs(occ, stuck))} pairs"
        )
        try:
            inner_repair(occ, planned, stuck, options, result, deadline, res)
        finally:
            left = len(colliding_pairs(occ, list(planned)))
            arrival = max(tr.arrival_s for tr in planned.values())
            print(
                f"    after the collision repair ({result.collision_repairs} neighbourhoods): {arrival:.2f} s, "
                f"{left} pairs left"
            )

    priority._in_order, priority._remove_collisions = uncapped, measured
    return saved


def _restore(priority, saved: tuple) -> None:
    priority._in_order, priority._remove_collisions, priority.LNS_PLANNINGS_PER_VEHICLE = saved


def failures(history: list[str]) -> Counter:
    """Per vehicle name, the lines of a pass's ``history`` that say it failed ("v012: why"): each is one
    time the vehicle could not be planned (and, with collisions on, one entry the in-collision cap
    counts, :func:`proxplan.planner.swarm.priority.in_collision_cap`)."""
    return Counter(m.group(1) for h in history if (m := FAILED.match(h)))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--layout", default="corridor")
    ap.add_argument("--n", type=int, default=64)
    ap.add_argument("--complete", action="store_true", help="passes with no in-collision cap (see module, 3)")
    ap.add_argument("--lns", type=int, default=1, help="collision repair's plannings per vehicle with --complete")
    ap.add_argument(
        "--plannings-per-vehicle", type=float, default=None, help="the stage's budget (default: SwarmOptions')"
    )
    args = ap.parse_args()

    import proxplan.planner.swarm.priority as priority
    from proxplan.planfile.scenario_load import scenario_from_dict
    from proxplan.planner.formations import LAYOUTS
    from proxplan.planner.sampling.ordering import lower_bound_makespan_s
    from proxplan.planner.swarm import SwarmOptions, swarm_problem
    from proxplan.planner.swarm.frozen import unfrozen_problem
    from proxplan.planner.swarm.prioritised_stage import horizon_steps, prioritised_stage

    scenario = scenario_from_dict(LAYOUTS[args.layout](args.n))
    problem, _, _ = unfrozen_problem(swarm_problem(scenario))
    lower_bound = lower_bound_makespan_s(scenario)
    opts = SwarmOptions(workers=1, reserve_starts=True)
    if args.plannings_per_vehicle is not None:
        opts = replace(opts, plannings_per_vehicle=args.plannings_per_vehicle)
    horizon = horizon_steps(lower_bound)
    print(
        f"{args.layout}-{args.n} fixed: bound {lower_bound:.2f} s, horizon {horizon} steps; "
        f"{cycle_pairs(problem, horizon)} ordered pairs with start and goal on the other's route"
    )
    saved = _complete_passes(priority, args.lns, lower_bound) if args.complete else None
    records: list[dict] = []
    inner = _passes_recorder(records)
    extra: dict = {}
    t0 = time.process_time()
    try:
        got = prioritised_stage(problem, lower_bound, opts, extra, progress=None, deadline=None)
    finally:
        priority._in_order = inner
        if saved is not None:
            _restore(priority, saved)
    print(f"  {extra['prioritised']}")
    print(f"  {extra['counts']}, {time.process_time() - t0:.1f} s CPU")
    if got is not None:
        makespan = max(tr.arrival_s for tr in got.tracks)
        print(f"  plan {makespan:.2f} s ({makespan / lower_bound:.2f}x) before re-timing")
    failed: Counter = Counter()
    for rec in records:
        _print_pass(rec)
        failed_here = failures(rec["history"])
        if any("more than the" in h for h in rec["history"]):
            print(
                f"    in-collision cap reached: {sum(failed_here.values())} failures of "
                f"{len(failed_here)} distinct vehicles"
            )
        failed.update(failed_here)
    for name, count in failed.most_common(6):
        a = problem.names.index(name)
        s, g = problem.starts_m[a].round(2).tolist(), problem.goals_m[a].round(2).tolist()
        print(f"  {name} failed {count}x: {s} -> {g}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
