"""The give-up diagnostic of benchmarks/why_gives_up.py (round 29A, docs/planner.md "Stop 67, round 29A"):
a pass's failures counted per vehicle as the in-collision cap counts them, and the patches of ``--complete``
(no cap, the collision repair's count per vehicle) put back afterwards."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import why_gives_up  # noqa: E402

import proxplan.planner.swarm.priority as priority  # noqa: E402
from proxplan.planner.swarm.priority_options import PriorityOptions  # noqa: E402


def test_failures_count_each_time_a_vehicle_failed_not_each_vehicle():
    """A shortened history of corridor-64's first pass (it had 9 failures of 3 vehicles); repairs, releases and
    the cap's own line are not failures."""
    history = [
        "v060 released the starts of v002, v003",
        "v016 past the predictions of v017, v028, v040",
        "v017 before v060, v016, v005",
        "v016: goes round in a circle with v017",
        "v017: goes round in a circle with v016",
        "v016: goes round in a circle with v028",
        "v028: goes round in a circle with v016, v017",
        "9 vehicles in collision, more than the 8 the collision repair has neighbourhoods for",
    ]
    got = why_gives_up.failures(history)
    assert got == {"v016": 2, "v017": 1, "v028": 1}
    assert sum(got.values()) == 4 and len(got) == 3


def test_complete_passes_lifts_the_cap_and_is_put_back():
    before = (priority._in_order, priority._remove_collisions, priority.LNS_PLANNINGS_PER_VEHICLE)
    seen: list[PriorityOptions] = []
    priority._in_order = lambda problem, order, options, **kw: seen.append(options)
    try:
        saved = why_gives_up._complete_passes(priority, 7, 4.0)
        assert priority.LNS_PLANNINGS_PER_VEHICLE == 7
        priority._in_order(None, [], PriorityOptions(max_repairs=1, max_in_collision=8))
        assert seen[-1].max_in_collision is None and seen[-1].max_repairs == 1
        why_gives_up._restore(priority, saved)
        assert priority._remove_collisions is before[1]
        assert priority.LNS_PLANNINGS_PER_VEHICLE == before[2]
    finally:
        priority._in_order, priority._remove_collisions, priority.LNS_PLANNINGS_PER_VEHICLE = before
