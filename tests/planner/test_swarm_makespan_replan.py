"""The makespan repair's planning of one neighbourhood member (proxplan.planner.swarm.makespan.replan,
stop 56 round 18C): the track it gives arrives before the step asked and meets no track in place; a
vehicle whose old track still fits keeps at least that, even where the single-vehicle planner finds
nothing; and the repair with it never lengthens a plan and keeps it verified."""

from __future__ import annotations

import pytest

from proxplan.planfile import scenario_from_dict
from proxplan.planner.formations import grid_reshuffle
from proxplan.planner.swarm import SwarmOptions, swarm_timed
from proxplan.planner.swarm import makespan as makespan_module
from proxplan.planner.swarm.makespan import replan
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.timing import assemble_plan
from proxplan.verify import verify_plan

HORIZON_MARGIN_STEPS = 100  # 5 s at the grid's 0.05 s, as the swarm layer's own horizon margin


def searched_before_repair(doc: dict):
    """(problem, the swarm layer's searched tracks before the makespan repair, horizon steps) of ``doc``."""
    sc = scenario_from_dict(doc, label="test scenario")
    _, info = swarm_timed(sc, SwarmOptions(workers=1, reserve_starts=True, makespan_repair=False))
    hand = info.hand_on
    assert hand is not None
    tracks = list(hand.searched.tracks)
    horizon = max(t.arrival_step for t in tracks) + HORIZON_MARGIN_STEPS
    return hand.problem, tracks, horizon


@pytest.fixture(scope="module")
def planned():
    return searched_before_repair(grid_reshuffle(16))


def _latest(tracks, k):
    return sorted(tracks, key=lambda t: (-t.arrival_step, t.agent))[:k]


def test_a_replanned_member_arrives_in_time_and_meets_no_track(planned):
    problem, tracks, horizon = planned
    for old in _latest(tracks, 4):
        occ = Occupancy(problem, tracks, horizon)
        occ.remove(old.agent)
        loose = replan(occ, old.agent, old, old.arrival_step + 1, through=False)
        assert loose is not None and loose.arrival_step <= old.arrival_step  # its old track fits at least
        assert not occ.conflicting_agents(loose)
        strict = replan(occ, old.agent, old, old.arrival_step, through=False)  # must be strictly earlier
        assert strict is None or (strict.arrival_step < old.arrival_step and not occ.conflicting_agents(strict))


def test_the_old_track_is_kept_where_the_single_vehicle_planner_finds_nothing(planned, monkeypatch):
    problem, tracks, horizon = planned
    monkeypatch.setattr(makespan_module, "plan_one", lambda occ, b, through, **kw: None)
    old = _latest(tracks, 1)[0]
    occ = Occupancy(problem, tracks, horizon)
    occ.remove(old.agent)
    got = replan(occ, old.agent, old, old.arrival_step + 1, through=False)
    assert got is not None and got.arrival_step <= old.arrival_step and not occ.conflicting_agents(got)
    # not where it would have to arrive earlier than it does
    assert replan(occ, old.agent, old, old.arrival_step, through=False) is None or (
        old.route_m is not None and len(old.route_m) > 2
    )


def test_the_repair_never_lengthens_and_the_plan_verifies():
    """grid-16 fixed with the makespan repair on (the default on a prioritised plan)."""
    sc = scenario_from_dict(grid_reshuffle(16), label="test scenario")
    timed, info = swarm_timed(sc, SwarmOptions(workers=1, reserve_starts=True, makespan_repair=True))
    repair = info.makespan_repair
    assert repair is not None
    assert repair.makespan_after_s <= repair.makespan_before_s
    assert repair.plannings <= makespan_module.budget(16)
    assert verify_plan(assemble_plan(sc, timed, method="swarm", notes=[]), sc) == []
