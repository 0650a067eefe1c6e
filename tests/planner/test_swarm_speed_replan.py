"""The makespan repair asks its filter (``fits``: on the stacked plan the verifier's sums around a
track, :meth:`proxplan.planner.swarm.verify_guard.VerifyGuard.fits`) only where the answer decides
(:func:`proxplan.planner.swarm.makespan.replan`, stop 61 round 23A): the same track as asking about
every candidate in turn (plan_one's track, then its route timed again to arrive before the one taken,
then the old track), for filters that take everything, nothing, or some tracks, and never more
questions."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from proxplan.planner.formations import LAYOUTS
from proxplan.planner.swarm.chain import time_chain
from proxplan.planner.swarm.makespan import replan
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.priority import plan_one

from .test_swarm_makespan_replan import searched_before_repair


@pytest.fixture(scope="module")
def planned():
    return searched_before_repair(LAYOUTS["pillar"](16))


def _digest(track) -> str | None:
    if track is None:
        return None
    return hashlib.sha1(np.ascontiguousarray(track.positions_m).tobytes()).hexdigest()


def _asked_in_turn(occ, b, old, worst, through, fits):
    """The rule before round 23A: every candidate asked in turn (the reference)."""
    track = plan_one(occ, b, through)
    if track is not None and not fits(occ, track, old):
        track = None
    route = None if old is None else old.route_m
    if route is not None and len(route) > 2:
        res = time_chain(occ, b, route, arrive_by=None if track is None else track.arrival_step - 1, through=through)
        if res is not None and (track is None or res.arrival_step < track.arrival_step):
            if fits(occ, res.track, old):
                track = res.track
    if (track is None or track.arrival_step >= worst) and old is not None and old.arrival_step < worst:
        if not occ.conflicting_agents(old) and fits(occ, old, old):
            track = old
    return None if track is None or track.arrival_step >= worst else track


class Counted:
    """A filter by a rule on the track, counting the questions about tracks other than the old one."""

    def __init__(self, rule):
        self.rule, self.asked = rule, 0

    def __call__(self, occ, track, old) -> bool:
        if track is old:
            return True  # as VerifyGuard.fits: the old track is taken as it was
        self.asked += 1
        return bool(self.rule(track))


RULES = {
    "everything": lambda t: True,
    "nothing": lambda t: False,
    "even arrivals": lambda t: t.arrival_step % 2 == 0,
    "by content": lambda t: int(_digest(t)[-1], 16) % 3 != 0,
}


@pytest.mark.parametrize("rule", sorted(RULES))
@pytest.mark.parametrize("through", [False, True])
def test_the_same_track_with_no_more_questions(planned, rule, through):
    problem, tracks, horizon = planned
    routed = 0
    for old in sorted(tracks, key=lambda t: (-t.arrival_step, t.agent))[:6]:
        routed += old.route_m is not None and len(old.route_m) > 2
        for worst in (old.arrival_step + 1, old.arrival_step, old.arrival_step - 10):
            occ = Occupancy(problem, tracks, horizon)
            occ.remove(old.agent)
            lazy, eager = Counted(RULES[rule]), Counted(RULES[rule])
            got = replan(occ, old.agent, old, worst, through, fits=lazy)
            want = _asked_in_turn(occ, old.agent, old, worst, through, eager)
            assert _digest(got) == _digest(want)
            assert (got is None) == (want is None)
            assert got is None or got.arrival_step == want.arrival_step
            assert lazy.asked <= eager.asked
    assert routed > 0  # some old tracks have a route to time again
