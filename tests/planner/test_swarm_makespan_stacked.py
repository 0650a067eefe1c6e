"""The makespan repair on the stacked plan (proxplan.planner.swarm.makespan, stop 57 round 19B): on by
default there, the latest vehicle planned again alone first (the others kept), a neighbourhood
stopped when a member cannot be planned even first; never longer, conflict-free, verified."""

from __future__ import annotations

import numpy as np

from proxplan.planner.swarm import makespan as makespan_module
from proxplan.planner.swarm.lns import colliding_pairs
from proxplan.planner.swarm.makespan import budget, shorten_makespan
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.timing import assemble_plan
from proxplan.verify import verify_plan

HORIZON_MARGIN_STEPS = 100  # 5 s at the grid's 0.05 s, as the swarm layer's own horizon margin


def _horizon(tracks) -> int:
    return max(t.arrival_step for t in tracks.values()) + HORIZON_MARGIN_STEPS


def test_the_stacked_plan_repaired_is_shorter_conflict_free_and_verified(stacked16):
    sc, problem, before = stacked16
    by_agent = dict(before)
    counts = shorten_makespan(problem, by_agent, _horizon(before), through=False, max_plannings=budget(16))
    assert counts["plannings"] <= budget(16)
    end_before = max(t.arrival_step for t in before.values())
    end_after = max(t.arrival_step for t in by_agent.values())
    assert counts["solo"] >= 1 and end_after < end_before  # the latest vehicle alone arrives earlier
    for tr in by_agent.values():
        np.testing.assert_allclose(tr.end_m, problem.goals_m[tr.agent], atol=1e-9)
    assert colliding_pairs(Occupancy(problem, list(by_agent.values()), _horizon(before)), range(16)) == set()
    timed = {problem.names[a]: t.timed_path() for a, t in by_agent.items()}
    assert verify_plan(assemble_plan(sc, timed, method="swarm", notes=[]), sc) == []


def test_a_member_that_cannot_be_planned_first_ends_its_neighbourhood(stacked16, monkeypatch):
    """With no member ever planned (replan gives None): every solo and every neighbourhood costs one
    planning (its first member), and no track changes."""
    _, problem, before = stacked16
    monkeypatch.setattr(makespan_module, "replan", lambda occ, b, old, worst, through: None)
    by_agent = dict(before)
    counts = shorten_makespan(problem, by_agent, _horizon(before), through=False, max_plannings=budget(16))
    assert counts["replaced"] == 0 and counts["tried"] >= 1
    end = max(t.arrival_step for t in before.values())
    latest = sum(t.arrival_step == end for t in before.values())  # each planned alone once
    assert counts["plannings"] == counts["tried"] + latest
    assert all(by_agent[a] is before[a] for a in before)
