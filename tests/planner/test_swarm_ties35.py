"""Round 35A (issue 37): ``canonical_assignment`` in about one assignment problem gives the same answer as round
34W's row-by-row search (the reference: the baseline arm of benchmarks/bench_assignment.py) and as brute force
over permutations: the lexicographically smallest assignment of least sum, whatever optimum (or non-optimum) the
solver returns."""

from __future__ import annotations

import itertools
import sys
from pathlib import Path

import numpy as np
import pytest

from proxplan.planner import ties as ties_module
from proxplan.planner.ties import canonical_assignment

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

# round 34W's row-by-row search, the reference: kept once, as the benchmark's baseline arm
from bench_assignment import baseline_row_by_row as _row_by_row  # noqa: E402


def _brute_force(cost: np.ndarray) -> list[int]:
    """Every permutation in lexicographic order; the first of least sum."""
    n = cost.shape[0]
    best, best_perm = None, None
    for perm in itertools.permutations(range(n)):
        s = int(cost[np.arange(n), perm].sum())
        if best is None or s < best:
            best, best_perm = s, list(perm)
    return best_perm


def _tied(rng: np.random.Generator, n: int) -> np.ndarray:
    return rng.integers(0, int(rng.integers(1, 5)), size=(n, n))


def test_the_empty_matrix_and_one_by_one():
    assert canonical_assignment(np.zeros((0, 0), dtype=np.int64)).tolist() == []
    assert canonical_assignment(np.array([[7]])).tolist() == [0]


def test_against_brute_force_up_to_seven():
    rng = np.random.default_rng(35)
    for _ in range(300):
        n = int(rng.integers(1, 8))
        cost = _tied(rng, n)
        assert canonical_assignment(cost).tolist() == _brute_force(cost), cost


def test_against_the_row_by_row_search_up_to_forty():
    rng = np.random.default_rng(3535)
    for trial in range(200):
        n = int(rng.integers(1, 41))
        cost = _tied(rng, n) if trial % 4 else rng.integers(0, 10**6, size=(n, n))
        assert canonical_assignment(cost).tolist() == _row_by_row(cost).tolist(), (trial, n)


def test_permuted_duplicates_give_the_same_goals():
    """Rows that are copies of each other (interchangeable vehicles at the same start): any permutation of the
    rows gives, row by row, the same multiset of columns, and the rows of equal costs take them in row order."""
    rng = np.random.default_rng(7)
    for _ in range(40):
        n = int(rng.integers(2, 30))
        base = rng.integers(0, 4, size=(int(rng.integers(1, n + 1)), n))
        cost = base[rng.integers(0, base.shape[0], size=n)]
        for _ in range(3):
            perm = rng.permutation(n)
            got = canonical_assignment(cost[perm])
            assert got.tolist() == _row_by_row(cost[perm]).tolist()
            assert sorted(got.tolist()) == list(range(n))


@pytest.mark.parametrize("answer", ["identity", "reversed_rows"])
def test_the_answer_does_not_depend_on_what_the_solver_returns(monkeypatch, answer):
    """A solver returning another optimum (rows reversed), or no optimum at all (the identity: the negative
    cycles of the residual graph are then applied), gives the same answer."""
    rng = np.random.default_rng(11)
    cases = [_tied(rng, int(rng.integers(1, 25))) for _ in range(60)]
    expected = [canonical_assignment(c).tolist() for c in cases]
    solver = ties_module.linear_sum_assignment

    def identity(cost):
        n = len(cost)
        return np.arange(n), np.arange(n)

    def reversed_rows(cost):
        rows, cols = solver(np.asarray(cost)[::-1])
        return (len(cost) - 1 - rows)[::-1], cols[::-1]

    monkeypatch.setattr(ties_module, "linear_sum_assignment", identity if answer == "identity" else reversed_rows)
    assert [canonical_assignment(c).tolist() for c in cases] == expected


def test_costs_too_wide_for_exact_potentials_are_refused():
    with pytest.raises(ValueError):
        canonical_assignment(np.array([[0, 2**61], [2**61, 0]], dtype=np.int64))


class _NormOneUlpUp:
    """numpy for one module, with ``linalg.norm`` 1 ulp up on non-zero values (the last bit another machine's
    numpy or Ruckig may give a straight line's length)."""

    class _Linalg:
        def __getattr__(self, name):
            return getattr(np.linalg, name)

        @staticmethod
        def norm(x, *args, **kwargs):
            v = np.linalg.norm(x, *args, **kwargs)
            up = np.where(v != 0, np.nextafter(v, np.inf), v)
            return up if np.ndim(v) else float(up)

    linalg = _Linalg()

    def __getattr__(self, name):
        return getattr(np, name)


def test_the_circle_16_by_type_plan_is_the_same_with_straight_lines_one_ulp_longer(monkeypatch):
    """Round 35A: circle-16 by type's digest parted between machines (and here with ``own_straight_track``'s norm
    1 ulp up) by a signed zero only: a position of 0 computed as -2.2e-16 hashed as -0.0 after rounding. With the
    digest blind to the sign of zero the plan is the recorded one, the straight lines' lengths moved by an ulp."""
    from proxplan.planfile import scenario_from_dict
    from proxplan.planner.formations import LAYOUTS
    from proxplan.planner.swarm import straight
    from proxplan.planner.swarm.plan import swarm_timed

    from .test_swarm_speed28_split import FLAT_LEVELS, PLANS, _digest

    doc = LAYOUTS["circle"](16)
    doc["assign_goals"] = "by_type"
    sc = scenario_from_dict(doc, label="test")
    monkeypatch.setattr(straight, "np", _NormOneUlpUp())
    timed, info = swarm_timed(sc, FLAT_LEVELS)
    assert _digest(timed, info) == PLANS[("circle", 16, "by_type")][1]
