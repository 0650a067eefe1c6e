"""Whether the makespan repair's stall rule (``makespan.STALL_ON_MAKESPAN``, round 29B) changes a plan:
every call of ``shorten_makespan`` made while planning a scenario is run twice on the same inputs,
with ``stall_on_makespan=False`` (the rule before round 29B: any replacement restarts the stall count)
on a copy first, then as the planner calls it (the default, the plan kept), and the two results are
compared: the makespan (s), the plannings spent, CPU s of each, and whether every track is the same
(sha256 of the tracks' positions rounded to 1e-6 m). Round 30S (issue 37: 29B checked the rule on the
64s and grid/circle-128 by replaying pickled inputs; this covers the 256s in one planning).

Usage (from outside the repository, so that the interpreter's installed proxplan is imported):
    cd /tmp && PY /path/to/benchmarks/stall_rule_check.py SCENARIO.yaml [--method swarm]
"""

from __future__ import annotations

import argparse
import contextlib
import hashlib
import io
import json
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np


def digest(by_agent: dict) -> str:
    """sha256 (16 hex digits) of every track's grid positions rounded to 1e-6 m, by agent."""
    h = hashlib.sha256()
    for a in sorted(by_agent):
        h.update(np.round(np.asarray(by_agent[a].positions_m, dtype=float), 6).tobytes())
    return h.hexdigest()[:16]


@dataclass
class Compared:
    """One makespan repair run with the stall rule off (before round 29B) and on (the planner's)."""

    tracks: int
    makespan_off_s: float
    makespan_on_s: float
    plannings_off: int
    plannings_on: int
    cpu_off_s: float
    cpu_on_s: float
    equal: bool  # every track the same (:func:`digest`)

    def row(self) -> str:
        return (
            f"repair of {self.tracks} tracks: off {self.makespan_off_s:.3f} s ({self.plannings_off} plannings, "
            f"{self.cpu_off_s:.1f} s CPU) | on {self.makespan_on_s:.3f} s ({self.plannings_on} plannings, "
            f"{self.cpu_on_s:.1f} s CPU) | tracks equal: {self.equal}"
        )


def both_rules(shorten: Callable, rows: list[Compared]) -> Callable:
    """``shorten`` (``makespan.shorten_makespan``'s signature) called twice per call: on a copy of the
    tracks with ``stall_on_makespan=False`` first, then on the caller's tracks with ``True`` (what the
    planner keeps, returned); each comparison appended to ``rows``."""

    def both(problem, by_agent, horizon_steps, **kw):
        copy = dict(by_agent)  # tracks are replaced in the dict, never changed in place
        c0 = time.process_time()
        off = shorten(problem, copy, horizon_steps, **{**kw, "stall_on_makespan": False})
        c1 = time.process_time()
        on = shorten(problem, by_agent, horizon_steps, **{**kw, "stall_on_makespan": True})
        c2 = time.process_time()
        rows.append(
            Compared(
                tracks=len(by_agent),
                makespan_off_s=max(t.arrival_s for t in copy.values()),
                makespan_on_s=max(t.arrival_s for t in by_agent.values()),
                plannings_off=off["plannings"],
                plannings_on=on["plannings"],
                cpu_off_s=c1 - c0,
                cpu_on_s=c2 - c1,
                equal=digest(copy) == digest(by_agent),
            )
        )
        return on

    return both


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenario")
    ap.add_argument("--method", default="swarm")
    args = ap.parse_args()

    from proxplan.planner.swarm import repair_stage

    rows: list[Compared] = []
    orig = repair_stage.shorten_makespan
    repair_stage.shorten_makespan = both_rules(orig, rows)  # this script's measurement; put back below
    from proxplan.cli import main as cli

    out = tempfile.mkdtemp(prefix="stall-check-")
    buf = io.StringIO()
    try:
        with contextlib.redirect_stdout(buf):
            cli(["plan", args.scenario, "--out", out, "--method", args.method, "--seed", "0", "--no-plot", "--json"])
    finally:
        repair_stage.shorten_makespan = orig
    doc = json.loads(buf.getvalue().strip().splitlines()[-1])
    print(f"{args.scenario}: makespan {doc['metrics']['makespan_s']:.3f} s, verify passed {doc['verify']['passed']}")
    for row in rows:
        print(row.row())
    return 0


if __name__ == "__main__":
    sys.exit(main())
