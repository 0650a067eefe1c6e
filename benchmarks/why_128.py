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

Usage (from outside the repository, so that the interpreter's installed proxplan is imported):
    cd /tmp && PY /path/to/benchmarks/why_128.py --layout pillar --n 128
    cd /tmp && PY /path/to/benchmarks/why_128.py --layout pillar --n 128 --one-pass --holding
"""

from __future__ import annotations

import argparse
import re
import time
from collections import Counter

import numpy as np

# a vehicle's name in a pass's history (swarm.priority writes "v012: why" for a vehicle that failed)
FAILED = re.compile(r"^(v\d+): (.*)$")


def _passes_recorder(records: list[dict]):
    """A wrapper of ``priority._in_order`` recording each pass's outcome into ``records``."""
    import proxplan.planner.swarm.priority as priority

    inner = priority._in_order

    def recorded(problem, order, options, **kw):
        rec = {"vehicles": problem.n_agents, "hold_s": options.hold_s, "cpu0": time.process_time()}
        records.append(rec)
        try:
            result = inner(problem, order, options, **kw)
        except priority.PrioritizedFailed as err:
            rec.update(outcome="gave up", planned=err.planned, history=list(err.history))
            rec["cpu_s"] = time.process_time() - rec.pop("cpu0")
            raise
        rec.update(outcome="plan", planned=result.planned, history=list(result.history))
        rec["cpu_s"] = time.process_time() - rec.pop("cpu0")
        return result

    priority._in_order = recorded
    return inner


def _print_pass(rec: dict) -> None:
    failed: Counter = Counter()
    reasons: Counter = Counter()
    trapped = 0
    for line in rec["history"]:
        m = FAILED.match(line)
        if m:
            failed[m.group(1)] += 1
            reasons[re.sub(r"v\d+", "v", m.group(2)).split(" (")[0]] += 1
        if " past the predictions of " in line or " released the starts of " in line:
            trapped += 1
    print(
        f"  pass of {rec['vehicles']} vehicles, hold {rec['hold_s']:g} s: {rec['outcome']} after "
        f"{rec['planned']} plannings, {rec['cpu_s']:.1f} s CPU; planned past reserved starts {trapped} times"
    )
    if rec["outcome"] == "gave up":
        print(f"    last: {rec['history'][-1][:200]}")
    if failed:
        print(f"    vehicles that failed ({len(failed)}): {dict(failed.most_common(8))}")
        print(f"    how: {dict(reasons.most_common(4))}")


def cycle_pairs(problem, horizon_steps: int) -> int:
    """Ordered pairs (a, b) with a's start and goal both within keep-out of b's ideal track (its flight
    alone): a must leave before b passes its start and arrive after b passes its goal."""
    from proxplan.planner.swarm.occupancy import Occupancy
    from proxplan.planner.swarm.reserve import ideal_track, starts_in_the_way
    from proxplan.planner.swarm.tracks import GridTrack

    A = problem.n_agents
    ideal = {a: ideal_track(problem, a, horizon_steps) for a in range(A)}
    starts_on = starts_in_the_way(problem, ideal, horizon_steps)
    parked = [GridTrack(a, int(problem.type_index[a]), problem.goals_m[a].copy(), []) for a in range(A)]
    goals = Occupancy(problem, parked, horizon_steps)
    return sum(len(starts_on[b] & (goals.conflicting_agents(tr) - {b})) for b, tr in ideal.items() if tr is not None)


def one_pass(args) -> int:
    """One prioritised pass of the whole swarm (see module, ``--one-pass``)."""
    import math

    import proxplan.planner.swarm.wave as wave
    from proxplan.planfile.scenario_load import scenario_from_dict
    from proxplan.planner.formations import LAYOUTS
    from proxplan.planner.sampling.ordering import lower_bound_makespan_s
    from proxplan.planner.swarm import SwarmOptions, swarm_problem
    from proxplan.planner.swarm.frozen import unfrozen_problem
    from proxplan.planner.swarm.prioritised_stage import horizon_steps, prioritised_budget
    from proxplan.planner.swarm.priority import (
        PrioritizedFailed,
        PriorityOptions,
        dependency_order,
        in_collision_cap,
        prioritized_tracks,
    )

    if args.whole_box:
        wave.route_box = lambda problem, s, g: (problem.lo_m[:2].copy(), problem.hi_m[:2].copy())
    scenario = scenario_from_dict(LAYOUTS[args.layout](args.n))
    problem, _, _ = unfrozen_problem(swarm_problem(scenario))
    lower_bound = lower_bound_makespan_s(scenario)
    horizon = horizon_steps(lower_bound)
    opts = SwarmOptions()
    n = problem.n_agents
    options = PriorityOptions(
        max_repairs=math.ceil(opts.repairs_per_vehicle * n),
        max_plannings=prioritised_budget(problem, opts),
        hold_s=args.hold_s,
        reserve_starts=True,
        through=False,
        give_up_early=True,
        max_in_collision=in_collision_cap(n),
        holding=args.holding,
    )
    print(
        f"{args.layout}-{args.n}: {cycle_pairs(problem, horizon)} ordered pairs with start and goal on the other's track"
    )
    t0 = time.process_time()
    try:
        result = prioritized_tracks(problem, dependency_order(problem), options, horizon_steps=horizon)
    except PrioritizedFailed as err:
        print(f"  gave up after {err.planned} plannings, {time.process_time() - t0:.1f} s CPU")
        print(f"  planned through a holding point: {sum(' via a holding point' in h for h in err.history)}")
        print(f"  last: {err.history[-1][:200]}")
        return 0
    makespan = max(tr.arrival_s for tr in result.tracks.values())
    print(
        f"  plan {makespan:.2f} s = {makespan / lower_bound:.2f}x after {result.planned} plannings, "
        f"{result.repairs} repairs, {result.held} through a holding point, {time.process_time() - t0:.1f} s CPU"
    )
    return 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--layout", default="pillar")
    ap.add_argument("--n", type=int, default=128)
    ap.add_argument("--one-pass", action="store_true", help="one prioritised pass only (see module)")
    ap.add_argument("--hold-s", type=float, default=1.0, help="with --one-pass: the hold of released starts, s")
    ap.add_argument("--holding", action="store_true", help="with --one-pass: PriorityOptions.holding")
    ap.add_argument("--whole-box", action="store_true", help="with --one-pass: the wavefront's whole-box fallback")
    args = ap.parse_args()
    if args.one_pass:
        return one_pass(args)

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
    return 0


def _starts(tr):
    """(start point, move) of each move of a track, m."""
    cur = np.asarray(tr.start_m, dtype=float)
    for _, mv in tr.moves:
        yield cur, mv
        cur = np.asarray(mv.end_m, dtype=float)


if __name__ == "__main__":
    raise SystemExit(main())
