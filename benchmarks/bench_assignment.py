"""Canonical assignment benchmark (round 35A, issue 37): round 34W's row-by-row search (the BASELINE arm, copied
here, not used by the project) against ``proxplan.planner.ties.canonical_assignment`` (one assignment problem,
exact dual potentials, the lowest perfect matching of the tight pairs), and ``scipy.optimize.linear_sum_assignment``
alone, on seeded random integer costs: ``distinct`` (0..10^12, almost no ties) and ``tied`` (0..3, many ties).

Usage:
    python benchmarks/bench_assignment.py [--n 64 128 256] [--repeat 3] [--seed 0] [--no-baseline]
        [--apply pillar-256 grid-256 ...]

The arms alternate within each case (baseline, new, LSA, then again), each timed by ``time.process_time`` (CPU s of
this process); the table gives the medians and the ratios baseline/new and new/LSA of the same run, and whether the
baseline and the new answer agree (they must). ``--apply LAYOUT-N ...``: also the whole by-type goal assignment
(``proxplan.planner.swarm.goals.apply_assignment``) of those layouts (``proxplan.planner.formations.LAYOUTS``) with
each arm in ``assign.assign_group`` (the baseline patched in), alternated, min of ``--repeat`` CPU s.
"""

from __future__ import annotations

import argparse
import math
import statistics
import time

import numpy as np
from scipy.optimize import linear_sum_assignment

from proxplan.planner.ties import canonical_assignment


def baseline_row_by_row(cost: np.ndarray) -> np.ndarray:
    """BASELINE ARM: round 34W's ``canonical_assignment`` (row by row the lowest column that keeps the least sum, up
    to one ``linear_sum_assignment`` per column below the optimum's), copied unchanged."""
    c = np.asarray(cost)
    n = c.shape[0]
    cf = c.astype(float)

    def least(rows: np.ndarray, cols: np.ndarray) -> tuple[float, np.ndarray]:
        if rows.size == 0:
            return 0.0, np.zeros(0, dtype=np.int64)
        sub = cf[np.ix_(rows, cols)]
        r, k = linear_sum_assignment(sub)
        out = np.empty(rows.size, dtype=np.int64)
        out[r] = cols[k]
        return float(sub[r, k].sum()), out

    out = np.empty(n, dtype=np.int64)
    free = np.arange(n)
    total, current = least(np.arange(n), free)
    for i in range(n):
        rest_rows = np.arange(i + 1, n)
        chosen = int(current[0])
        for j in free[free < chosen]:
            others = free[free != j]
            if rest_rows.size and cf[i, j] + cf[np.ix_(rest_rows, others)].min(axis=1).sum() > total + 0.5:
                continue
            s, sol = least(rest_rows, others)
            if math.isclose(cf[i, j] + s, total, rel_tol=0.0, abs_tol=0.5):
                chosen, current = int(j), np.concatenate([[j], sol])
                break
        out[i] = chosen
        total -= cf[i, chosen]
        free = free[free != chosen]
        current = current[1:]
    return out


def _lsa(cost: np.ndarray) -> np.ndarray:
    return linear_sum_assignment(cost.astype(float))[1]


def _timed(fn, cost: np.ndarray) -> tuple[float, np.ndarray]:
    t0 = time.process_time()
    out = fn(cost)
    return time.process_time() - t0, out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, nargs="+", default=[64, 128, 256])
    ap.add_argument("--repeat", type=int, default=3, help="alternations of the arms per case")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--no-baseline", action="store_true", help="leave out the (slow) baseline arm")
    ap.add_argument("--apply", nargs="*", default=[], metavar="LAYOUT-N", help="also apply_assignment on these")
    args = ap.parse_args()
    rng = np.random.default_rng(args.seed)
    arms = {"lsa": _lsa, "new": canonical_assignment}
    if not args.no_baseline:
        arms = {"baseline": baseline_row_by_row, **arms}
    print("case        n  " + "  ".join(f"{a + '_s':>10}" for a in arms) + "   base/new    new/lsa  same")
    for n in args.n:
        for kind, high in (("distinct", 10**12), ("tied", 4)):
            cost = rng.integers(0, high, size=(n, n), dtype=np.int64)
            times: dict[str, list[float]] = {a: [] for a in arms}
            answers: dict[str, np.ndarray] = {}
            for _ in range(args.repeat):
                for name, fn in arms.items():
                    t, out = _timed(fn, cost)
                    times[name].append(t)
                    answers[name] = out
            med = {a: statistics.median(v) for a, v in times.items()}
            base = f"{med['baseline'] / med['new']:10.1f}" if "baseline" in med else f"{'-':>10}"
            same = str(bool(np.array_equal(answers["baseline"], answers["new"]))) if "baseline" in answers else "-"
            print(
                f"{kind:9s} {n:4d}  "
                + "  ".join(f"{med[a]:10.4f}" for a in arms)
                + f" {base} {med['new'] / med['lsa']:10.1f}  {same}"
            )
    for case in args.apply:
        _apply(case, args.repeat)
    return 0


def _apply(case: str, repeat: int) -> None:
    """apply_assignment of ``case`` (layout-N, by type) with the baseline and the new arm in turn."""
    from proxplan.planfile import scenario_from_dict
    from proxplan.planner.formations import LAYOUTS
    from proxplan.planner.swarm import assign
    from proxplan.planner.swarm.goals import apply_assignment

    layout, n = case.rsplit("-", 1)
    doc = LAYOUTS[layout](int(n))
    doc["assign_goals"] = "by_type"
    sc = scenario_from_dict(doc, label="bench")
    times: dict[str, list[float]] = {"baseline": [], "new": []}
    goals: dict[str, dict] = {}
    try:
        for _ in range(repeat):
            for name, fn in (("baseline", baseline_row_by_row), ("new", canonical_assignment)):
                assign.canonical_assignment = fn
                t0 = time.process_time()
                _, record = apply_assignment(sc)
                times[name].append(time.process_time() - t0)
                goals[name] = record["goal_of"]
    finally:
        assign.canonical_assignment = canonical_assignment
    b, k = min(times["baseline"]), min(times["new"])
    print(
        f"apply_assignment {case} by_type: baseline {b:.2f} s, new {k:.2f} s CPU (min of {repeat}), "
        f"ratio {b / k:.1f}, same goals {goals['baseline'] == goals['new']}"
    )


if __name__ == "__main__":
    raise SystemExit(main())
