"""Round 34W (issue 37, "the same seed gives the same plan"): a choice among candidates of equal cost is the same
on every machine (proxplan.planner.ties). A machine differs from another by the last bits of a cost, or by
which of several optimal assignments its solver returns; both are simulated here on cases with exact ties."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.physics import KinematicLimits
from proxplan.planner import ties as ties_module
from proxplan.planner.swarm import assign_group
from proxplan.planner.ties import canonical_assignment, quantised, tie_key

LIMITS = KinematicLimits(1.5, 3.0, 12.0)

# two starts at opposite corners of a 1 m square, two goals at the other corners: both assignments cost the
# same (every line 1 m long), an exact tie by symmetry
STARTS = np.array([[0.0, 0.0, 1.0], [1.0, 1.0, 1.0]])
GOALS = np.array([[1.0, 0.0, 1.0], [0.0, 1.0, 1.0]])


def _ulp(x: float, toward: float) -> float:
    return float(np.nextafter(x, toward))


@pytest.mark.parametrize("toward", [-np.inf, np.inf])
def test_an_assignment_with_an_exact_tie_is_the_same_with_a_start_moved_by_one_ulp(toward):
    """A machine that rounds the last bit of one start's coordinate the other way makes one of the two equal
    assignments 1 ulp cheaper; on main the solver then took it (one way for +1 ulp, the other for -1 ulp)."""
    plain, _ = assign_group(STARTS, GOALS, LIMITS)
    moved = STARTS.copy()
    moved[1, 0] = _ulp(moved[1, 0], toward)
    nudged, _ = assign_group(moved, GOALS, LIMITS)
    assert nudged.tolist() == plain.tolist() == [0, 1]


def test_an_assignment_with_exact_ties_does_not_depend_on_which_optimum_the_solver_returns(monkeypatch):
    """A solver that returns another optimum (here: the same solver on the rows in reverse order, its answer put
    back in the rows' order) gives the same assignment: a 4 x 4 chessboard of 1 m squares, the starts on its dark
    squares, the goals on its light ones, where many assignments of 1 m lines tie."""
    cells = np.array([(x, y) for x in range(4) for y in range(4)], dtype=float)
    dark = (cells.sum(axis=1) % 2) == 0
    starts = np.column_stack([cells[dark], np.ones(8)])
    goals = np.column_stack([cells[~dark], np.ones(8)])
    plain, _ = assign_group(starts, goals, LIMITS)
    solver = ties_module.linear_sum_assignment

    def reversed_rows(cost):
        rows, cols = solver(np.asarray(cost)[::-1])
        return (len(cost) - 1 - rows)[::-1], cols[::-1]

    monkeypatch.setattr(ties_module, "linear_sum_assignment", reversed_rows)
    other, _ = assign_group(starts, goals, LIMITS)
    assert other.tolist() == plain.tolist()


def test_canonical_assignment_is_the_lowest_column_first_among_equal_sums():
    cost = np.array([[1, 1, 5], [1, 1, 5], [5, 5, 1]])
    assert canonical_assignment(cost).tolist() == [0, 1, 2]
    assert canonical_assignment(cost[[1, 0, 2]]).tolist() == [0, 1, 2]
    with pytest.raises(ValueError):
        canonical_assignment(cost.astype(float))


def test_tie_key_rounds_away_the_last_bits():
    length = 3.055806702001944
    assert tie_key(length, 1e-9) == tie_key(_ulp(length, 4.0), 1e-9) == tie_key(_ulp(length, 0.0), 1e-9)
    assert quantised(np.array([length, _ulp(length, 4.0)]), 1e-9).tolist() == [tie_key(length, 1e-9)] * 2
