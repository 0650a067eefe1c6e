"""The makespan repair's stall budget (proxplan.planner.swarm.makespan.STALL_PLANNINGS, stop 58 round
20A): the search stops once that many plannings in a row replaced nothing, the count restarts at
each gain; it acts wherever the repair runs (by default prioritised and stacked plans, round 21A)."""

from __future__ import annotations

import pytest

from proxplan.planner.swarm import SwarmOptions
from proxplan.planner.swarm import makespan as makespan_module
from proxplan.planner.swarm.makespan import budget, shorten_makespan
from proxplan.planner.swarm.repair_stage import repairs as _repairs
from proxplan.planner.swarm.stage import Stage

HORIZON_MARGIN_STEPS = 100  # 5 s at the grid's 0.05 s, as the swarm layer's own horizon margin
NO_STALL = 10**6  # a stall budget never reached on 16 vehicles (their whole budget is 48 plannings)


def _repair(problem, before, stall: int):
    by_agent = dict(before)
    horizon = max(t.arrival_step for t in before.values()) + HORIZON_MARGIN_STEPS
    counts = shorten_makespan(
        problem, by_agent, horizon, through=False, max_plannings=budget(problem.n_agents), stall_plannings=stall
    )
    return counts, by_agent


def test_a_search_without_gains_stops_after_the_stall_budget(stacked16, monkeypatch):
    """With no member ever planned (replan gives None) the search spends more than 2 plannings
    without a stall budget; with a stall budget of 2 it stops by then (a neighbourhood that does not
    fit in what is left is not started), no track changed."""
    _, problem, before = stacked16
    monkeypatch.setattr(makespan_module, "replan", lambda occ, b, old, worst, through: None)
    unbounded, _ = _repair(problem, before, NO_STALL)
    assert unbounded["plannings"] > 2 and unbounded["replaced"] == 0
    counts, by_agent = _repair(problem, before, 2)
    assert 1 <= counts["plannings"] <= 2 and counts["replaced"] == 0
    assert all(by_agent[a] is before[a] for a in before)


def test_the_stall_count_restarts_at_each_gain(stacked16):
    """With a stall budget of one planning the search goes on past it after the latest vehicle's
    solo planning shortens the plan (the count restarts there), and ends no later than without a
    stall budget, which here gains nothing more."""
    _, problem, before = stacked16
    _, unbounded = _repair(problem, before, NO_STALL)
    counts, by_agent = _repair(problem, before, 1)
    assert counts["solo"] >= 1 and counts["plannings"] > 1
    end_before = max(t.arrival_step for t in before.values())
    end_after = max(t.arrival_step for t in by_agent.values())
    assert end_after < end_before
    assert end_after == max(t.arrival_step for t in unbounded.values())


@pytest.mark.parametrize(("stage", "runs"), [("stacked", True), ("lattice", False), ("prioritised", True)])
def test_the_repair_runs_by_default_except_on_the_lattice_plan(stage, runs):
    """On by default on the stacked plan again (stop 59 round 21A: its result there checked by the
    verifier), never on the lattice plan unless asked (``makespan_repair=True``)."""
    found = Stage(tracks=[], stage=stage, coordination="", routes=lambda a: [])
    assert _repairs(SwarmOptions(), found) is runs
    assert _repairs(SwarmOptions(makespan_repair=False), found) is False
    assert _repairs(SwarmOptions(makespan_repair=True), found) is True
