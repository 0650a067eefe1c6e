"""A discovered term is tested only when most half-samples picked it or a feature standing for it
(identify.consensus, issue 35)."""

from __future__ import annotations

import numpy as np

from proxplan.identify.consensus import REPRESENTS_R2, represented_counts
from proxplan.identify.crossval import GroupSums


def _sums(rng: np.random.Generator) -> GroupSums:
    n, n_groups = 4000, 4
    a = rng.normal(size=n)
    a_lag = 0.95 * a + np.sqrt(1 - 0.95**2) * rng.normal(size=n)  # a near-copy: shares 90 % of a's variance
    b = rng.normal(size=n)  # another signal: shares ~0 % with a
    c = 0.6 * a + 0.8 * rng.normal(size=n)  # shares 36 % with a: related, but not standing for it
    x = np.column_stack([a, a_lag, b, c])
    group = np.repeat(np.arange(n_groups), n // n_groups)
    return GroupSums.build(x, rng.normal(size=n), np.ones(n), group, n_groups, ["a", "a_lag", "b", "c"])


def test_a_pick_stands_for_its_near_copy_and_not_for_another_signal() -> None:
    sums = _sums(np.random.default_rng(0))
    picks = [["a"], ["a_lag"], ["b"], ["a", "b"], ["c"], []]
    counts = represented_counts(sums, np.ones(4), picks)
    assert counts["a"] == 3 and counts["a_lag"] == 3  # halves 0, 1, 3: each stands for the other
    assert counts["b"] == 2  # halves 2 and 3 only
    assert counts["c"] == 1  # shares 36 % < REPRESENTS_R2 with a: only its own pick
    assert REPRESENTS_R2 == 0.5


def test_only_the_weighted_groups_set_what_stands_for_what() -> None:
    rng = np.random.default_rng(1)
    n = 2000
    a = rng.normal(size=n)
    d = np.where(np.arange(n) < n // 2, a, rng.normal(size=n))  # equal to a in group 0, unrelated in group 1
    group = (np.arange(n) >= n // 2).astype(int)
    sums = GroupSums.build(np.column_stack([a, d]), rng.normal(size=n), np.ones(n), group, 2, ["a", "d"])
    picks = [["a"], ["d"]]
    assert represented_counts(sums, np.array([1.0, 0.0]), picks) == {"a": 2, "d": 2}
    assert represented_counts(sums, np.array([0.0, 1.0]), picks) == {"a": 1, "d": 1}


def test_no_picks_no_counts() -> None:
    assert represented_counts(_sums(np.random.default_rng(2)), np.ones(4), [[], []]) == {}


def test_the_tested_members_are_the_halves_consensus_not_the_best_of_many() -> None:
    from proxplan.identify.consensus import tested_members
    from proxplan.identify.stability import PI_MIN, Stability

    g1, g2, g3 = "force_z_N|temporal:above", "torque_x_Nm|temporal:above", "torque_y_Nm|side"
    stab = Stability({g1: 0.9, g2: 0.95, g3: 0.3}, PI_MIN, 2.0, 20, 30)
    member = {
        "force_z_N*above_near_lag380ms_1": 0.5,  # stood for by 80 % of the halves: tested
        "force_z_N*above_near_lag570ms_1": 0.3,  # stood for by 80 % too (its near-copy): tested
        "torque_x_Nm*base_ty_lp800ms_Nm": 0.45,  # the group's consensus, 50 %: none above PI_MIN, so this one
        "torque_x_Nm*W*above_core_flat_lp50ms_1": 0.05,  # picked once: never the group's stand-in
        "torque_y_Nm*side_near_x_1": 0.3,  # its group is not stable
    }
    represented = {
        "force_z_N*above_near_lag380ms_1": 0.8,
        "force_z_N*above_near_lag570ms_1": 0.8,
        "torque_x_Nm*base_ty_lp800ms_Nm": 0.5,
        "torque_x_Nm*W*above_core_flat_lp50ms_1": 0.1,
        "torque_y_Nm*side_near_x_1": 0.9,
    }
    assert tested_members(member, represented, stab) == [
        "force_z_N*above_near_lag380ms_1",
        "torque_x_Nm*base_ty_lp800ms_Nm",
        "force_z_N*above_near_lag570ms_1",
    ]


def test_a_fold_counts_a_term_only_where_its_own_search_would_have_tested_it_or_its_stand_in() -> None:
    """The cross-validation of the selection step uses the member rule, not the group's stability: a flight's
    fold that tests another, unrelated member of the group does not make the term eligible there."""
    from proxplan.identify.consensus import PickTally

    a, a_copy, other = "base_fz_lag50ms_N", "base_fz_lag75ms_N", "base_fz_lowpass_N"  # one group, temporal:above
    names = [a, a_copy, other]
    stands = np.array([[1, 1, 0], [1, 1, 0], [0, 0, 1]], dtype=bool)  # a and its copy stand for each other
    key = "force_z_N*" + a

    def fold(picks: list[list[str]]) -> PickTally:
        t = PickTally(len(picks))
        t.add("force_z_N", picks, names, stands)
        return t

    assert fold([[a], [a], [a], [other]]).eligible([key], 5) == {key}  # tests the term itself
    assert fold([[a_copy], [a_copy], [a_copy], []]).eligible([key], 5) == {key}  # tests its stand-in
    assert fold([[other], [other], [other], [a]]).eligible([key], 5) == set()  # tests another signal
    assert fold([[a], [], [], []]).eligible([key], 5) == set()  # the group is not stable without the flight
    # the same halves, the group counted as one label, would have made it eligible in the third fold
    assert fold([[other], [other], [other], [a]]).stability(5).stable("force_z_N|temporal:above")
