"""A joint manoeuvre of a group of vehicles passing together, and where it can depart against tracks
fixed before it (issue 37 item 5; used by :mod:`proxplan.planner.swarm.passes` and
:mod:`proxplan.planner.swarm.stagger`).

A :class:`JointMove` gives each member its moves as grid-step offsets after one common departure;
:func:`place_joint` finds the earliest common departure that the other tracks of an
:class:`~proxplan.planner.swarm.occupancy.Occupancy` allow (holds at the start before it, at the goal
after it, the flown samples, exactly as :func:`~proxplan.planner.swarm.arc_timing.time_arc` asks them).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.problem import SwarmProblem
from proxplan.planner.swarm.tracks import GridTrack, Move

__all__ = ["JointMove", "member_key", "moving", "place_joint"]


@dataclass(frozen=True)
class JointMove:
    """One joint manoeuvre of a component: per member its moves ((grid steps after the common
    departure, move), in time order; () where it rests) and the waypoint chain it is flown along (start,
    the arc's middle, goal; its straight line; start, the point aside, start for a resting member
    stepping aside; None at rest)."""

    members: tuple[int, ...]
    moves: tuple[tuple[tuple[int, Move], ...], ...]
    routes: tuple[np.ndarray | None, ...]
    label: str
    # the members' tracks departing at step 0, built when first asked (place_joint asks them for every
    # placement tried: 24 000 tracks of 50 us each on pillar-64 by type; round 28S)
    _zero: list[GridTrack] = field(default_factory=list, init=False, compare=False, repr=False)

    @property
    def steps(self) -> int:
        """Grid steps from the common departure to the last member's arrival."""
        return max((k + mv.steps for legs in self.moves for k, mv in legs), default=0)

    def tracks(self, problem: SwarmProblem, depart_step: int) -> list[GridTrack]:
        """The members' tracks departing at ``depart_step``."""
        out = []
        for a, legs, route in zip(self.members, self.moves, self.routes):
            moves = [(depart_step + k, mv) for k, mv in legs]
            out.append(GridTrack(a, int(problem.type_index[a]), problem.starts_m[a].copy(), moves, route_m=route))
        return out

    def tracks_at_zero(self, problem: SwarmProblem) -> list[GridTrack]:
        """:meth:`tracks` departing at step 0, kept (read-only: do not change them)."""
        if not self._zero:
            self._zero.extend(self.tracks(problem, 0))
        return self._zero

    def member(self, i: int) -> JointMove:
        """The joint move of its ``i``-th member alone (same offsets, label)."""
        return JointMove((self.members[i],), (self.moves[i],), (self.routes[i],), self.label)


def moving(problem: SwarmProblem, a: int) -> bool:
    """Whether agent ``a`` is free to move and its goal is not its start."""
    return not problem.pinned[a] and float(np.linalg.norm(problem.goals_m[a] - problem.starts_m[a])) > 1e-9


def member_key(a: int, legs: tuple[tuple[int, Move], ...], route: np.ndarray | None) -> tuple:
    """What fixes a member's track in a joint move: its agent, its legs' offsets (grid steps) and its waypoint
    chain (each move is the rest-to-rest line, the arc through the chain's middle or the step aside and back
    that the chain and the offsets name, :func:`~proxplan.planner.swarm.pass_moves.joint_moves`), with the kinds
    of its moves."""
    kinds = tuple((k, type(mv).__name__, mv.steps) for k, mv in legs)
    return (a, kinds, None if route is None else np.asarray(route, dtype=float).tobytes())


def _first_true(mask: np.ndarray) -> int:
    hit = np.flatnonzero(mask)
    return int(hit[0]) if hit.size else mask.size


def place_joint(occ: Occupancy, jm: JointMove, *, arrive_by: int | None = None) -> int | None:
    """The earliest common departure step of ``jm`` against the tracks of ``occ`` (every member
    holding its start before it, flying its moves from it, holding its end for good after them; a
    member without moves holding its start for good), arriving by step ``arrive_by`` (None: within the
    horizon), or None."""
    problem = occ.problem
    T = occ.horizon
    last = T - 1 if arrive_by is None else min(T - 1, arrive_by)
    allowed = np.zeros(T, dtype=bool)
    allowed[: max(0, last - jm.steps + 1)] = True
    for tr in jm.tracks_at_zero(problem):
        a = tr.agent
        if not tr.moves:
            if occ.forbidden_holds(a, tr.start_m).any():
                return None
            continue
        allowed[_first_true(occ.forbidden_holds(a, tr.start_m)) :] = False
        goal_bad = np.flatnonzero(occ.forbidden_holds(a, tr.end_m))
        allowed[: max(0, int(goal_bad[-1]) + 1 - tr.arrival_step) if goal_bad.size else 0] = False
        window = np.flatnonzero(allowed)
        if not window.size:
            return None
        q = tr.position_at_steps(np.arange(tr.arrival_step + 1))
        lo, hi = int(window[0]), int(window[-1]) + 1
        allowed &= ~occ.forbidden_departures(a, q, from_step=lo, until_step=hi)
    window = np.flatnonzero(allowed)
    return int(window[0]) if window.size else None
