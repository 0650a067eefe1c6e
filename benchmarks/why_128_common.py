"""Shared printing of the why_128 diagnostics (benchmarks/why_128.py; split by mode in round 28A): the passes of
prioritised planning recorded and printed, and the rests of the latest tracks."""

from __future__ import annotations

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


def _rests(tr, min_s: float = 0.25) -> list[tuple[float, float, np.ndarray]]:
    """(from s, duration s, position m) of each rest of ``tr`` lasting ``min_s`` or more before its arrival."""
    still = ~tr.moving[: tr.arrival_step + 1]
    out = []
    k = 0
    while k < still.size:
        if still[k]:
            j = k
            while j < still.size and still[j]:
                j += 1
            if j < still.size and (j - k) * 0.025 >= min_s:
                out.append((k * 0.025, (j - k) * 0.025, tr.positions_m[k]))
            k = j
        else:
            k += 1
    return out


def _print_rests(problem, tracks: dict, count: int) -> None:
    """The ``count`` latest of ``tracks`` (by agent): each rest (at its start, at its goal or aside) and
    when its goal is clear of every other track for good (the stream has passed it), s."""
    from proxplan.planner.swarm.occupancy import Occupancy
    from proxplan.planner.timing.profile import rest_to_rest

    horizon = max(tr.arrival_step for tr in tracks.values()) + 2
    occ = Occupancy(problem, list(tracks.values()), horizon)
    for tr in sorted(tracks.values(), key=lambda tr: -tr.arrival_s)[:count]:
        a = tr.agent
        s, g = problem.starts_m[a], problem.goals_m[a]
        alone = rest_to_rest(float(np.linalg.norm(g - s)), problem.limits[a], 0.025).duration_s
        occ.remove(a)
        busy = np.flatnonzero(occ.forbidden_holds(a, g))
        occ.put(tr)
        clear = (busy[-1] + 1) * 0.025 if busy.size else 0.0
        where = []
        for t0, dt, q in _rests(tr):
            at = (
                "start"
                if np.linalg.norm(q - s) < 1e-6
                else "goal"
                if np.linalg.norm(q - g) < 1e-6
                else (f"aside ({q[0]:.2f}, {q[1]:.2f}, {q[2]:.2f})")
            )
            where.append(f"{dt:.2f} s at {at} from {t0:.2f} s")
        print(
            f"  {problem.names[a]}: arrives {tr.arrival_s:.2f} s ({alone:.2f} s alone); its goal clear of the others "
            f"for good from {clear:.2f} s; rests: {'; '.join(where) or 'none'}"
        )


def _starts(tr):
    """(start point, move) of each move of a track, m."""
    cur = np.asarray(tr.start_m, dtype=float)
    for _, mv in tr.moves:
        yield cur, mv
        cur = np.asarray(mv.end_m, dtype=float)
