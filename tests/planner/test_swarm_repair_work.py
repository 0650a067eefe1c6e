"""The makespan repair on by default on the stacked plan (stop 59 round 21A): its stall budget counted
in work (plannings x the horizon each searches, proxplan.planner.swarm.makespan.STALL_WORK_STEPS), and
its result on the stacked plan checked by the verifier, the tracks before it kept where it fails."""

from __future__ import annotations

from proxplan.planner.swarm import SwarmOptions
from proxplan.planner.swarm import makespan as makespan_module
from proxplan.planner.swarm.makespan import STALL_WORK_STEPS, budget, shorten_makespan, stall_budget
from proxplan.planner.swarm.repair_stage import makespan_stage as _makespan_stage
from proxplan.planner.swarm.verify_guard import VerifyGuard
from proxplan.planner.timing import assemble_plan
from proxplan.verify import verify_plan


def test_the_stall_budget_is_work_so_a_longer_horizon_gets_fewer_plannings():
    """The same work: twice the horizon, half the plannings (never fewer than one)."""
    assert stall_budget(720) == STALL_WORK_STEPS // 720
    assert stall_budget(1440) == stall_budget(720) // 2
    assert stall_budget(4 * 720) < stall_budget(720)
    assert stall_budget(10 * STALL_WORK_STEPS) == 1
    assert stall_budget(100, work_steps=1000) == 10


def test_without_a_stall_count_the_search_stops_on_its_work(stacked16, monkeypatch):
    """With no member ever planned (replan gives None) and a horizon long enough that the work budget
    allows 3 plannings, the search stops by then; with a horizon of 100 times less it goes on (its
    work budget is then far above the 48 plannings of the whole search)."""
    _, problem, before = stacked16
    monkeypatch.setattr(makespan_module, "replan", lambda occ, b, old, worst, through: None)
    short = max(t.arrival_step for t in before.values()) + 100
    assert stall_budget(short) > budget(16)
    free = shorten_makespan(problem, dict(before), short, through=False, max_plannings=budget(16))
    assert free["plannings"] > 3 and free["replaced"] == 0
    long = STALL_WORK_STEPS // 3
    assert stall_budget(long) == 3
    counts = shorten_makespan(problem, dict(before), long, through=False, max_plannings=budget(16))
    assert 1 <= counts["plannings"] <= 3 and counts["replaced"] == 0


def _end(tracks) -> int:
    return max(t.arrival_step for t in tracks.values())


def test_a_repair_that_fails_the_check_gives_the_tracks_before_it_back(stacked16):
    """The repair shortens grid-16's stacked plan; told that its result fails the verifier, the stage
    hands back the very tracks it was given, and says so; told that it passes, the shorter tracks."""
    _, problem, before = stacked16
    asked: list[int] = []

    def fails(by_agent) -> bool:
        asked.append(_end(by_agent))
        return False

    by_agent = dict(before)
    info = _makespan_stage(problem, by_agent, SwarmOptions(), progress=None, deadline=None, check=fails)
    assert info.replaced >= 1 and asked and asked[0] < _end(before)  # asked about the shorter tracks
    assert info.verify_failed and info.makespan_after_s == info.makespan_before_s
    assert all(by_agent[a] is before[a] for a in before)
    kept = dict(before)
    info = _makespan_stage(problem, kept, SwarmOptions(), progress=None, deadline=None, check=lambda _: True)
    assert not info.verify_failed and _end(kept) < _end(before)


def test_with_the_verifier_as_the_check_the_stage_hands_on_a_plan_that_verifies(stacked16):
    """The guard the swarm layer builds (verify_guard.VerifyGuard) on grid-16's stacked plan: what the stage hands
    on passes the verifier, and the guard agrees with the verifier on it."""
    sc, problem, before = stacked16
    check = VerifyGuard(sc, problem, problem, ())
    by_agent = dict(before)
    info = _makespan_stage(problem, by_agent, SwarmOptions(), progress=None, deadline=None, check=check)
    timed = {problem.names[a]: t.timed_path() for a, t in by_agent.items()}
    assert verify_plan(assemble_plan(sc, timed, method="swarm", notes=[]), sc) == []
    assert check(by_agent)
    assert info.makespan_after_s <= info.makespan_before_s
