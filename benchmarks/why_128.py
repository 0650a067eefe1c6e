"""Why a 128-vehicle plan of the swarm layer is long (issue 37, round 20B): which stage gives it, why
prioritised planning gave up, and what sets the makespan of the plan kept.

Runs ``swarm_timed`` in this process on a named layout with the options the pipeline uses for fixed
goals (one worker, reserved starts) and prints:

* every pass of prioritised planning (the whole swarm's and each stacked level's): its vehicles, hold,
  plannings made, vehicles planned when it gave up, how it gave up, the vehicles that failed and how
  often, and how many times a vehicle had to be planned past reserved starts (start-trapped);
* CPU at the first progress message of each stage (where the time goes);
* the plan kept: its stage, makespan against the bound, and the latest vehicle of the tracks before
  re-timing: its moves, the time it flies and the time it waits, against its own straight line.

With ``--one-pass`` (round 21B) it runs instead one pass of prioritised planning of the whole swarm in
the dependency order with the stage's options (reserved starts, hold ``--hold-s``, the stage's repair,
planning and in-collision counts) and prints how it ended: plannings, CPU, vehicles still queued when it
gave up, vehicles planned through a holding point (``--holding``: ``PriorityOptions.holding``, swarm.holding),
and how many ordered pairs (a, b) have a's start AND goal within keep-out of b's track flown alone (a must
leave before b passes and arrive after it). ``--whole-box``: the wavefront searches the whole free box
when the start-goal box grown by ``MARGIN_M`` holds no route (not only where the straight line crosses a
wall; a diagnosis, monkeypatched here).

With ``--lattice`` (round 22B) it runs instead LaCAM alone on the stage's lattice for ``--seeds`` seeds
(each with the whole count budget, so the plans of the stage's seeds while the first search finishes)
and prints per seed the lattice's own counts (steps, configurations, proposals, CPU) and the lock-step
makespan with and without the dependency execution; then, for the first-arriving seed: moves per vehicle
and vertices revisited, per step the movers, the vehicles at their goals, the vehicles moved away from
their goals, the step's longest and mean move and its dependency groups (lockstep; the largest one's
movers); the latest vehicles
(moves, metres flown, the first step at their goals); how many loops of a vehicle (leaving a vertex and
coming back) could be cut by staying there against everyone else's moves, and how many pairs of
consecutive steps could be flown as one straight step (every pair passing the synchronous test).

The default mode also prints (round 23B) the latest vehicles of the FINAL tracks (re-timed and repaired):
each rest of 0.25 s or more (at the start, at the goal or aside, from when) and from when the vehicle's goal
is clear of every other track for good (a vehicle resting at its start until then waits for the stream to
pass its goal).

With ``--flow`` (round 23B) it measures what streams in lanes could give: the vehicles grouped by direction of
travel (``direction_groups``), each group planned alone by the swarm layer (no other group in its way: what
lanes that separate the groups completely would give at best), the lane routes (``lane_routes``: the middle
leg offset sideways and in height by ``FLOW_LATERAL_REACHES`` x ``FLOW_DZ_M``, the offset whose flight passes
the fewest other starts and goals kept) and how many other starts and goals the best route of each vehicle
still passes, and the flow timing along them (``flow_timing``: each vehicle after those whose starts its route
passes and before those whose goals it passes, ties the longest flight first; exact timing one vehicle after
another, the others' starts reserved; started again at most ``FLOW_RESTARTS`` times with the vehicle that could
not be timed first), with its latest vehicles' rests where it times every vehicle.

With ``--level K`` (round 26B) it plans instead level K of the stacked plan (bottom first) alone by
prioritised planning with the level options (``plan._level_options``; ``--level-options`` JSON changes them,
e.g. ``'{"orders": ["far goals first"]}'``), and prints the level's head-on structure (ordered pairs flying
opposite ways within reach of each other, and the most vehicles on one straight line), each pass, and the
head of the history of the first pass that gave up.

Usage (from outside the repository, so that the interpreter's installed proxplan is imported):
    cd /tmp && PY /path/to/benchmarks/why_128.py --layout pillar --n 128
    cd /tmp && PY /path/to/benchmarks/why_128.py --layout pillar --n 128 --one-pass --holding
    cd /tmp && PY /path/to/benchmarks/why_128.py --layout corridor --n 128 --lattice --seeds 4
    cd /tmp && PY /path/to/benchmarks/why_128.py --layout corridor --n 64 --flow
    cd /tmp && PY /path/to/benchmarks/why_128.py --layout corridor --n 128 --level 1
"""

from __future__ import annotations

import argparse
import time

import numpy as np

# the modes live in modules of their own (round 28A); the names the tests use are re-exported here
from why_128_common import _passes_recorder, _print_pass, _print_rests, _rests, _starts
from why_128_flow import flow
from why_128_lattice import lattice_counts
from why_128_level import head_on, level_alone
from why_128_one_pass import one_pass

# the --flow diagnostic's lane routes and flow timing (round 23B) live in the planner since round 27A
from proxplan.planner.swarm.lanes import direction_groups, flow_timing, lane_routes

__all__ = ["_rests", "direction_groups", "flow_timing", "head_on", "lane_routes", "main"]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--layout", default="pillar")
    ap.add_argument("--n", type=int, default=128)
    ap.add_argument("--one-pass", action="store_true", help="one prioritised pass only (see module)")
    ap.add_argument("--hold-s", type=float, default=1.0, help="with --one-pass: the hold of released starts, s")
    ap.add_argument("--holding", action="store_true", help="with --one-pass: PriorityOptions.holding")
    ap.add_argument("--whole-box", action="store_true", help="with --one-pass: the wavefront's whole-box fallback")
    ap.add_argument("--lattice", action="store_true", help="LaCAM alone on the stage's lattice (see module)")
    ap.add_argument("--seeds", type=int, default=4, help="with --lattice: seeds 0 .. N-1")
    ap.add_argument("--flow", action="store_true", help="direction groups alone, lane routes, flow timing (see module)")
    ap.add_argument("--group", type=int, default=None, help="with --flow: direction group K alone")
    ap.add_argument("--keep-right", action="store_true", help="with --flow: lane routes offset to the right only")
    ap.add_argument("--level", type=int, default=None, help="level K of the stacked plan alone (see module)")
    ap.add_argument("--level-options", default="{}", help="with --level: SwarmOptions changes, JSON")
    ap.add_argument("--history", type=int, default=40, help="with --level: lines of the failing pass's history")
    args = ap.parse_args()
    if args.level is not None:
        return level_alone(args)
    if args.flow:
        return flow(args)
    if args.one_pass:
        return one_pass(args)
    if args.lattice:
        return lattice_counts(args)

    import proxplan
    import proxplan.planner.swarm.priority as priority
    from proxplan.planfile.scenario_load import scenario_from_dict
    from proxplan.planner.formations import LAYOUTS
    from proxplan.planner.swarm import SwarmOptions, swarm_timed
    from proxplan.planner.timing.profile import rest_to_rest

    print(f"proxplan from {proxplan.__file__}")
    scenario = scenario_from_dict(LAYOUTS[args.layout](args.n))
    records: list[dict] = []
    inner = _passes_recorder(records)
    stages: list[tuple[float, str]] = []
    t0 = time.process_time()

    def progress(message: str, fraction: float | None = None) -> None:
        head = "".join(ch for ch in message if not ch.isdigit()).split("(")[0].strip()
        if not stages or stages[-1][1] != head:
            stages.append((time.process_time() - t0, message[:70]))

    try:
        timed, info = swarm_timed(scenario, SwarmOptions(workers=1, reserve_starts=True), progress=progress)
    finally:
        priority._in_order = inner
    cpu = time.process_time() - t0
    print(
        f"{args.layout}-{args.n}: stage {info.stage}, makespan {info.makespan_s:.2f} s = "
        f"{info.makespan_s / info.lower_bound_s:.2f}x the bound {info.lower_bound_s:.2f} s "
        f"(before re-timing {info.initial_makespan_s:.2f} s), {cpu:.1f} s CPU"
    )
    print(f"  coordination: {info.coordination}")
    print(f"  stacked: {info.stacked}")
    if info.lattice is not None:
        print(f"  lattice: {info.lattice.steps} steps, {info.lattice.nodes} configurations")
    print(f"  re-timing: {info.retiming}")
    print("\npasses of prioritised planning (in the order run)")
    for rec in records:
        _print_pass(rec)
    print("\nprogress (process CPU at the first message of each stage)")
    for t, head in stages:
        print(f"  {t:7.1f} s  {head}")
    hand_on = info.hand_on
    assert hand_on is not None
    problem = hand_on.problem
    tracks = hand_on.searched.tracks
    print(f"\nthe latest vehicles of the tracks before re-timing ({hand_on.searched.stage})")
    for tr in sorted(tracks, key=lambda tr: -tr.arrival_s)[:5]:
        a = tr.agent
        flying = sum(mv.steps for _, mv in tr.moves) * 0.025
        length = float(np.linalg.norm(problem.goals_m[a] - problem.starts_m[a]))
        alone = rest_to_rest(length, problem.limits[a], 0.025).duration_s
        route = sum(float(np.linalg.norm(mv.end_m - s)) for s, mv in _starts(tr))
        first = tr.moves[0][0] * 0.025 if tr.moves else 0.0
        print(
            f"  {problem.names[a]}: arrives {tr.arrival_s:.2f} s ({tr.arrival_s / alone:.1f}x its straight line "
            f"{alone:.2f} s, {length:.2f} m); {len(tr.moves)} moves, {route:.2f} m flown; flies {flying:.2f} s, "
            f"waits {tr.arrival_s - flying:.2f} s (first move at {first:.2f} s)"
        )
    final = hand_on.tracks
    if final is not None:
        print("\nthe latest vehicles of the final tracks (re-timed and repaired): rests of 0.25 s or more, where")
        _print_rests(problem, final, 5)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
