"""Round 37B: the makespan repair asks :func:`proxplan.planner.swarm.single.plan_one` for a track
arriving before the neighbourhood's latest (``arrive_by``) and times routes to that bound
(:func:`proxplan.planner.swarm.makespan.replan`). The bounded answer is the unbounded one cut at the
bound (its track where it arrives in time, else None), on real occupancies and on every case of
plan_one's three searches (straight line, wavefront route, slow route: none, late or in time), and
replan gives the same track as the full rule (every search unbounded, every candidate asked)."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from proxplan.planner.formations import LAYOUTS
from proxplan.planner.swarm import single
from proxplan.planner.swarm.chain import ChainResult
from proxplan.planner.swarm.makespan import replan
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.single import plan_one
from proxplan.planner.swarm.tracks import GridTrack

from .test_swarm_makespan_replan import searched_before_repair
from .test_swarm_speed_replan import Counted, _asked_in_turn, _digest


@pytest.fixture(scope="module")
def planned():
    return searched_before_repair(LAYOUTS["pillar"](16))


def _cut(track: GridTrack | None, by: int) -> GridTrack | None:
    return track if track is not None and track.arrival_step <= by else None


@pytest.mark.parametrize("through", [False, True])
def test_bounded_plan_one_is_the_unbounded_cut(planned, through):
    problem, tracks, horizon = planned
    some_late = some_in_time = 0
    for old in sorted(tracks, key=lambda t: (-t.arrival_step, t.agent))[:6]:
        occ = Occupancy(problem, tracks, horizon)
        occ.remove(old.agent)
        full = plan_one(occ, old.agent, through)  # None for some (stop 56: found none, though one exists)
        at = old.arrival_step if full is None else full.arrival_step
        for by in (at + 3, at, at - 1, old.arrival_step - 1, horizon, 0):
            got = plan_one(occ, old.agent, through, arrive_by=by)
            want = _cut(full, by)
            assert _digest(got) == _digest(want)
            some_late += want is None
            some_in_time += want is not None
    assert some_late > 0 and some_in_time > 0


class _Searches:
    """plan_one's searches stubbed: the straight line, the wavefront route and the slow route each
    with an earliest arrival (None: no timing in the horizon); a bounded timing returns it only where
    it arrives by the bound, as time_chain does."""

    def __init__(self, straight, wave, slow):
        self.arrival = {2: straight, 3: wave, 4: slow}  # keyed by the chain's number of waypoints
        self.arrives: dict[int, int] = {}  # id of a track handed out -> its arrival step

    def wave_route(self, occ, agent, s, g, *, heights=False, pace=None, grow_m=None):
        n = 4 if pace is not None else 3
        if self.arrival[n] == "no route":
            return None
        return np.linspace(s, g, n)

    def time_chain(self, occ, agent, w, *, arrive_by=None, through=True):
        a = self.arrival[len(w)]
        if a is None or a == "no route" or (arrive_by is not None and a > arrive_by):
            return None
        track = GridTrack(agent, 0, np.asarray(w[0], dtype=float), [], route_m=np.asarray(w))
        self.arrives[id(track)] = a
        return ChainResult(track, a)


def test_every_case_of_the_three_searches(planned, monkeypatch):
    problem, tracks, horizon = planned
    occ = Occupancy(problem, tracks, horizon)
    agent = tracks[0].agent
    unobstructed = single.rest_to_rest(
        float(np.linalg.norm(problem.goals_m[agent] - problem.starts_m[agent])), problem.limits[agent], single.GRID_DT_S
    ).steps
    u = unobstructed
    # no search arrives before the straight line's rest-to-rest time (the bound plan_one relies on)
    straights = [None, u, u + 5, u + 20]
    others = [None, "no route", u + 2, u + 10, u + 30]
    slow_cases = 0
    for straight, wave, slow in itertools.product(straights, others, others):
        stub = _Searches(straight, wave, slow)
        monkeypatch.setattr(single, "wave_route", stub.wave_route)
        monkeypatch.setattr(single, "time_chain", stub.time_chain)
        full = plan_one(occ, agent, True)
        for by in (u - 1, u, u + 2, u + 5, u + 10, u + 25, u + 40):
            got = plan_one(occ, agent, True, arrive_by=by)
            want = None if full is None or stub.arrives[id(full)] > by else full
            assert (got is None) == (want is None), (straight, wave, slow, by)
            if want is not None:
                assert got.route_m.shape == want.route_m.shape  # the same search's track
                assert stub.arrives[id(got)] == stub.arrives[id(want)]
                slow_cases += len(want.route_m) == 4
    assert slow_cases > 0


@pytest.mark.parametrize("rule", ["everything", "nothing", "even arrivals"])
def test_replan_matches_the_full_rule(planned, rule):
    problem, tracks, horizon = planned
    rules = {
        "everything": lambda t: True,
        "nothing": lambda t: False,
        "even arrivals": lambda t: t.arrival_step % 2 == 0,
    }
    for old in sorted(tracks, key=lambda t: (-t.arrival_step, t.agent))[:6]:
        for worst in (old.arrival_step + 1, old.arrival_step, old.arrival_step - 10):
            for through in (False, True):
                occ = Occupancy(problem, tracks, horizon)
                occ.remove(old.agent)
                for fits in (None, Counted(rules[rule])):
                    got = replan(occ, old.agent, old, worst, through, fits=fits)
                    want = _asked_in_turn(occ, old.agent, old, worst, through, fits or (lambda o, t, b: True))
                    assert _digest(got) == _digest(want)
