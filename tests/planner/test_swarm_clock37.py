"""Round 37S (issue 37: "budgets are counts, so the same seed gives the same plan on any machine"): with no
``deadline`` the swarm layer reads the wall clock only to report its times, never to decide. Under a clock
running a thousand times as fast as the real one (any wall-clock budget would run out at once, as on a
machine a thousand times slower) each case plans exactly the plan recorded in
``test_swarm_speed28_split.PLANS`` (one prioritised plan, one stacked plan), and the clock was read."""

from __future__ import annotations

import time

import pytest

from proxplan.planfile import scenario_from_dict
from proxplan.planner.formations import LAYOUTS
from proxplan.planner.swarm.plan import swarm_timed

from .test_swarm_speed28_split import FLAT_LEVELS, PLANS, _digest

CLOCK_FACTOR = 1000.0  # how much faster the patched clock runs than the real one (dimensionless)
CASES = [("corridor", 12, "fixed"), ("grid", 16, "fixed")]


@pytest.mark.parametrize("case", CASES, ids=lambda c: f"{c[0]}-{c[1]}-{c[2]}")
def test_a_clock_running_a_thousand_times_as_fast_gives_the_same_plan(case, monkeypatch):
    layout, n, _ = case
    real = time.perf_counter
    t0 = real()
    reads = []

    def fast() -> float:  # s, CLOCK_FACTOR x the real time elapsed since t0
        reads.append(1)
        return t0 + CLOCK_FACTOR * (real() - t0)

    for name in ("perf_counter", "monotonic", "time", "process_time"):
        monkeypatch.setattr(time, name, fast)
    scenario = scenario_from_dict(LAYOUTS[layout](n), label="test")
    timed, info = swarm_timed(scenario, FLAT_LEVELS)
    monkeypatch.undo()
    stage, digest, _ = PLANS[case]
    assert reads, "the swarm layer did not read the patched clock: the test would prove nothing"
    assert info.stage == stage
    assert _digest(timed, info) == digest
