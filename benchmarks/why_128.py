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

Usage (from outside the repository, so that the interpreter's installed proxplan is imported):
    cd /tmp && PY /path/to/benchmarks/why_128.py --layout pillar --n 128
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


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--layout", default="pillar")
    ap.add_argument("--n", type=int, default=128)
    args = ap.parse_args()

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
