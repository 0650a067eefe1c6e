"""Staggered joint moves (proxplan.planner.swarm.stagger, round 28S): one occupancy per joint move with a
fixed horizon, and each member's delay kept under the members placed before it, give the delays of the
direct computation (each member placed against a new occupancy of exactly the members before it, the
horizon just past their arrivals: round 27S's), member by member; joint moves kept their zero-departure
tracks unchanged."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.planner.swarm.joint import JointMove, moving, place_joint
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.pass_moves import conflict_components, conflict_free, joint_moves
from proxplan.planner.swarm.stagger import MAX_STAGGER_STEPS, leaving_order, staggered
from proxplan.planner.swarm.straight import straight_step_conflicts

from .test_swarm_by_type_passes import _assigned

JOINT_MOVES_PER_GROUP = 24  # joint moves of each group compared (the shortest first), to keep the test short


def _direct(problem, jm: JointMove) -> JointMove | None:
    """Round 27S's staggering: each member against a new occupancy of the members before it."""
    moves = list(jm.moves)
    placed = []
    for i in leaving_order(problem, jm.members):
        one = jm.member(i)
        d = 0
        if placed:
            horizon = max(tr.arrival_step for tr in placed) + one.steps + MAX_STAGGER_STEPS + 2
            d = place_joint(Occupancy(problem, placed, horizon), one, arrive_by=one.steps + MAX_STAGGER_STEPS)
        if d is None:
            return None
        moves[i] = tuple((k + d, mv) for k, mv in jm.moves[i])
        placed += one.tracks(problem, d)
    return JointMove(jm.members, tuple(moves), jm.routes, jm.label)


def _offsets(jm: JointMove | None):
    return None if jm is None else [[k for k, _ in legs] for legs in jm.moves]


@pytest.mark.parametrize("layout", ["grid", pytest.param("pillar", marks=pytest.mark.slow)])
def test_staggered_delays_are_the_direct_ones(layout):
    _, _, problem = _assigned(layout, 64)
    pairs = [(i, j) for i, j in straight_step_conflicts(problem) if i != j]
    compared = staggered_some = 0
    for comp in conflict_components(pairs):
        if not all(moving(problem, a) for a in comp):
            continue
        moves = [jm for jm in joint_moves(problem, comp, checked=False) if not conflict_free(problem, jm)]
        for jm in moves[:JOINT_MOVES_PER_GROUP]:
            got, want = staggered(problem, jm), _direct(problem, jm)
            assert _offsets(got) == _offsets(want), jm.label
            assert _offsets(staggered(problem, jm)) == _offsets(want)  # asked again: from the memo
            compared += 1
            staggered_some += got is not None and any(k for legs in got.moves for k, _ in legs)
    assert compared >= 10 and staggered_some >= 5


def test_tracks_at_zero_are_the_tracks_departing_at_zero():
    _, _, problem = _assigned("grid", 16)
    pairs = [(i, j) for i, j in straight_step_conflicts(problem) if i != j]
    jm = joint_moves(problem, conflict_components(pairs)[0], checked=False)[0]
    for a, b in zip(jm.tracks_at_zero(problem), jm.tracks(problem, 0)):
        assert a.agent == b.agent and np.array_equal(a.positions_m, b.positions_m)
        assert np.array_equal(a.moving, b.moving)
    assert jm.tracks_at_zero(problem) is jm.tracks_at_zero(problem)


def test_a_bounded_fitting_stops_only_where_the_joint_move_arrives_too_late():
    """grid-64 by type's v012+v020+v027+v028 (every joint move staggered): asked for an arrival before step
    ``below``, the fitting stops early (a Partial) only where the full fitting arrives at ``below`` or later,
    at most at that arrival, and otherwise gives the full fitting; asked in full after it, the same."""
    from proxplan.planner.swarm.pass_moves import fitted, fitted_below
    from proxplan.planner.swarm.stagger import Partial

    problems = [_assigned("grid", 64)[2] for _ in range(2)]  # one fitted in full, one bounded first
    full_p, bounded_p = problems
    members = tuple(sorted(full_p.names.index(n) for n in ("v012", "v020", "v027", "v028")))
    stopped = 0
    for jm, jm_b in zip(joint_moves(full_p, members, checked=False), joint_moves(bounded_p, members, checked=False)):
        full = fitted(full_p, jm)
        for below in (jm.steps, jm.steps + 4, 10**6):
            got = fitted_below(bounded_p, jm_b, below)
            if isinstance(got, Partial):
                stopped += 1
                assert below <= got.arrival_lower and (full is None or got.arrival_lower <= full.steps)
                assert full is None or full.steps >= below
            else:
                assert _offsets(got) == _offsets(full) and (got is None or got.label == full.label)
        assert _offsets(fitted(bounded_p, jm_b)) == _offsets(full)
    assert stopped >= 5
