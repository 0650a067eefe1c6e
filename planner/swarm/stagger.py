"""A joint move whose members conflict leaving together, flown with its members leaving one after
another (issue 37 item 5; round 27S, made cheaper in round 28S; used by
:func:`proxplan.planner.swarm.pass_moves.fitted`).

A member's fastest arc (:mod:`proxplan.planner.timing.path_law`) may reach a partner's start before the
partner has left it. :func:`staggered` then takes the members in :func:`leaving_order` (a member before
those flying to its start) and delays each member's moves by the fewest grid steps (0 to
:data:`MAX_STAGGER_STEPS`) that leave it conflict-free against the members delayed before it
(:func:`~proxplan.planner.swarm.joint.place_joint` of the member alone against their tracks: the test by
which the passing stage places a component against the tracks fixed before it).

*Cost (round 28S).* pillar-64 by type staggers 340 joint moves of groups of 8-12 (4.0 s of its 12.4 s
of CPU): each member was placed against a new occupancy of all the members before it (O(n^2) track
insertions a joint move), and the joint moves of a group share most of their members' moves (the
variants with one member on its line share every other member's arc). Now

* one occupancy per joint move, each member's tracks put in once it is delayed. Its horizon,
  :func:`_horizon`, is fixed for the whole joint move; :func:`place_joint`'s answer does not depend on
  it as long as it exceeds every placed member's arrival and the asked member's latest arrival
  (``arrive_by``) by one step: the departures asked are d <= :data:`MAX_STAGGER_STEPS`, a hold at the
  start or along the flown samples is asked at steps below the latest arrival, and a track parked at
  the goal forbids holding it from the parked track's arrival on (every departure, at any horizon);
* a member's delay is kept in ``problem.static_memo`` under what fixes it: the members placed before
  it (:func:`~proxplan.planner.swarm.joint.member_key` with its delay) and its own key, so a joint move
  sharing that prefix with one staggered before asks nothing again. (Keyed by the members placed before
  it that come near it only: on pillar-64 every member of a group comes within reach of every other,
  and the test cost 1.7 s.)

The delays are those of the direct computation (tests/planner/test_swarm_law28_stagger.py checks them
member by member on grid-64 and pillar-64 by type).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial

import numpy as np

from proxplan.planner.swarm.joint import JointMove, member_key, place_joint
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.problem import SwarmProblem
from proxplan.planner.swarm.tracks import GridTrack

# a joint move's member leaves at most this many grid steps after the common departure where the members
# conflict leaving together (0.4 s: a joint move one reach-factor wider costs 2-5 steps, so a longer delay
# rarely pays; a count, not tuned; round 27S)
MAX_STAGGER_STEPS = 16
# a goal this close to another member's start is that start (m): goals and starts are given points
SAME_POINT_M = 1e-6

__all__ = ["MAX_STAGGER_STEPS", "SAME_POINT_M", "Partial", "leaving_order", "staggered"]


def leaving_order(problem: SwarmProblem, members: tuple[int, ...]) -> list[int]:
    """Indices into ``members``: a member before those whose goal is its start (it leaves what they
    reach), else in the members' order (also round a cycle: a swap, a rotation)."""
    s, g = problem.starts_m, problem.goals_m
    after = {
        i: {j for j, b in enumerate(members) if j != i and np.linalg.norm(g[b] - s[members[i]]) <= SAME_POINT_M}
        for i in range(len(members))
    }
    waits_for = {j: {i for i in after if j in after[i]} for j in range(len(members))}
    order: list[int] = []
    while len(order) < len(members):
        left = [j for j in range(len(members)) if j not in order]
        ready = [j for j in left if not waits_for[j] - set(order)]
        order.append(min(ready) if ready else min(left))
    return order


def _horizon(jm: JointMove) -> int:
    """Grid steps of the occupancy a member of ``jm`` is placed against: one more than the latest arrival
    a placed member can have (its moves delayed by :data:`MAX_STAGGER_STEPS`) plus the longest member's
    moves delayed as much (the asked member's latest arrival), one step to spare (see module)."""
    return 2 * (jm.steps + MAX_STAGGER_STEPS) + 2


class _Placed:
    """The members of a joint move delayed so far: their tracks and, once a delay is asked, the occupancy
    of those tracks (horizon :func:`_horizon`), each member's tracks put in as it is placed."""

    def __init__(self, problem: SwarmProblem, jm: JointMove):
        self.problem, self.jm = problem, jm
        self.tracks: list[GridTrack] = []
        self.occ: Occupancy | None = None

    def add(self, tracks: list[GridTrack]) -> None:
        self.tracks += tracks
        if self.occ is not None:
            for tr in tracks:
                self.occ.put(tr)

    def delay(self, one: JointMove) -> int | None:
        """The fewest grid steps (<= :data:`MAX_STAGGER_STEPS`) ``one`` (a member alone) is delayed by to be
        conflict-free against the tracks placed, or None (:func:`place_joint`)."""
        if self.occ is None:
            self.occ = Occupancy(self.problem, self.tracks, _horizon(self.jm))
        return place_joint(self.occ, one, arrive_by=one.steps + MAX_STAGGER_STEPS)


@dataclass
class Partial:
    """A staggering stopped early: the members placed before it already arrive at step ``arrival_lower`` or
    later, so the staggered joint move arrives no earlier (its arrival is the latest member's)."""

    arrival_lower: int


def staggered(problem: SwarmProblem, jm: JointMove, *, below: int | None = None) -> JointMove | Partial | None:
    """``jm`` with its members leaving one after another (see module), or None where a member has no
    delay up to :data:`MAX_STAGGER_STEPS`; with ``below``: a :class:`Partial` as soon as the members placed
    arrive at step ``below`` or later (the caller wants only an earlier arrival; nothing of the joint move
    is kept but the members' delays, so asked again it goes on from there at the cost of lookups)."""
    moves = list(jm.moves)
    keys = [member_key(a, legs, route) for a, legs, route in zip(jm.members, jm.moves, jm.routes)]
    placed = _Placed(problem, jm)
    prefix: tuple = ()  # (key, delay) of each member placed, in leaving order
    delays = []
    arrival = 0  # the latest arrival of the members placed (grid steps after the common departure)
    for i in leaving_order(problem, jm.members):
        one = jm.member(i)
        d: int | None = 0
        if placed.tracks:
            d = problem.static_memo.get(("stagger", prefix, keys[i]), partial(placed.delay, one))
        if d is None:
            return None
        moves[i] = tuple((k + d, mv) for k, mv in jm.moves[i])
        arrival = max(arrival, d + one.steps)
        if below is not None and arrival >= below:
            return Partial(arrival)
        placed.add(problem.static_memo.get(("stagger track", keys[i], d), partial(one.tracks, problem, d)))
        prefix += ((keys[i], d),)
        if d:
            delays.append(f"{problem.names[jm.members[i]]} +{d}")
    return JointMove(jm.members, tuple(moves), jm.routes, f"{jm.label}, staggered ({', '.join(delays)})")
