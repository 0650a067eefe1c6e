"""The stall-rule check of benchmarks/stall_rule_check.py (round 30S, docs/planner.md "Stop 68, round 30S"): each
makespan repair run twice, the rule off on a copy and on for the caller, differences in the tracks reported and
the caller's tracks left as the rule on made them."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import stall_rule_check  # noqa: E402

from proxplan.planner.swarm.tracks import GridTrack  # noqa: E402


def _parked(agent: int, x_m: float) -> GridTrack:
    return GridTrack(agent, 0, np.array([x_m, 0.0, 1.0]), [])


def _fake_shorten(moved_when_off: bool):
    """A repair that moves agent 1 by 1 m with the rule on, and also with it off where ``moved_when_off``."""

    def shorten(problem, by_agent, horizon_steps, **kw):
        if kw["stall_on_makespan"] or moved_when_off:
            by_agent[1] = _parked(1, 5.0)
        return {"plannings": 7 if kw["stall_on_makespan"] else 9}

    return shorten


def test_both_rules_reports_equal_tracks_and_keeps_the_rule_on():
    rows: list[stall_rule_check.Compared] = []
    tracks = {0: _parked(0, 0.0), 1: _parked(1, 4.0)}
    got = stall_rule_check.both_rules(_fake_shorten(True), rows)(None, tracks, 100, through=False)
    assert got == {"plannings": 7}
    assert tracks[1].positions_m[0, 0] == 5.0  # the caller's tracks: the rule on
    (row,) = rows
    assert row.equal and (row.plannings_off, row.plannings_on) == (9, 7) and row.tracks == 2


def test_both_rules_reports_different_tracks():
    rows: list[stall_rule_check.Compared] = []
    tracks = {0: _parked(0, 0.0), 1: _parked(1, 4.0)}
    stall_rule_check.both_rules(_fake_shorten(False), rows)(None, tracks, 100, through=False)
    assert not rows[0].equal
    assert tracks[1].positions_m[0, 0] == 5.0
    assert stall_rule_check.digest(tracks) != stall_rule_check.digest({0: _parked(0, 0.0), 1: _parked(1, 4.0)})
