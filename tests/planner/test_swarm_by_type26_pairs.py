"""A joint move's members checked pair by pair (proxplan.planner.swarm.passes, issue 37 item 5, round 26S):
the verdict equals the all-members check (``conflict_free``) on every joint move of the named layouts'
components, the conflicting ones included; each pair is asked once per problem."""

from __future__ import annotations

import pytest

from proxplan.planfile import scenario_from_dict
from proxplan.planner.formations import layout_doc
from proxplan.planner.swarm.goals import apply_assignment
from proxplan.planner.swarm.pass_moves import _free, _pairs_free, conflict_components, conflict_free, joint_moves
from proxplan.planner.swarm.problem import swarm_problem
from proxplan.planner.swarm.straight import straight_step_conflicts


def _problem(layout: str, n: int):
    scenario, record = apply_assignment(scenario_from_dict(layout_doc(layout, n, assign="by_type"), label="test"))
    assert record is not None
    return swarm_problem(scenario)


@pytest.mark.parametrize(("layout", "n"), [("grid", 16), ("circle", 16), ("grid", 20)])
def test_pair_by_pair_equals_all_members(layout, n):
    """Every joint move (unchecked) of every component: the same verdict both ways; both verdicts occur,
    and some joint move of three or more members is judged (not only pairs)."""
    problem = _problem(layout, n)
    pairs = [(i, j) for i, j in straight_step_conflicts(problem) if i != j]
    verdicts = []
    larger = 0
    for comp in conflict_components(pairs):
        for jm in joint_moves(problem, comp, checked=False):
            whole = conflict_free(problem, jm)
            assert _pairs_free(problem, jm) == whole, (comp, jm.label)
            verdicts.append(whole)
            larger += len(jm.members) >= 3
    assert True in verdicts and False in verdicts
    assert larger > 0


def test_each_pair_is_asked_once_per_problem():
    """The components' joint moves of grid-20 by type share their members' moves: asking every one makes
    fewer pair checks (pair entries kept in the problem's memo) than the pairs of all joint moves, and asking
    them again computes nothing (no memo miss)."""
    problem = _problem("grid", 20)
    pairs = [(i, j) for i, j in straight_step_conflicts(problem) if i != j]
    moves = [jm for comp in conflict_components(pairs) for jm in joint_moves(problem, comp, checked=False)]
    memo = problem.static_memo
    first = [_free(problem, jm) for jm in moves]
    asked = sum(1 for key in memo._answers if isinstance(key, tuple) and key[0] == "pair free")
    assert asked > 0
    every_pair = sum(len(jm.members) * (len(jm.members) - 1) // 2 for jm in moves)
    assert asked < every_pair
    again = memo.misses
    assert [_free(problem, jm) for jm in moves] == first
    assert memo.misses == again
