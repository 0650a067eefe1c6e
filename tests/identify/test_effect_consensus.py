"""Library effects follow the discovered terms' rule (identify.consensus, issue 35): an effect may be kept when
most half-samples picked it or an effect standing for it, and a candidate acting on fewer than two flights does not count in the Bonferroni m (Tarone 1990)."""

from __future__ import annotations

import numpy as np

from proxplan.identify.consensus import represented_shares, sets_standing_for, split_vote_eligible
from proxplan.identify.crossval import GroupSums
from proxplan.identify.heldout_select import can_be_tested
from proxplan.identify.stability import PI_MIN, Stability


def _sums(rng: np.random.Generator) -> GroupSums:
    """Columns: t (always fitted), e1, e2 (a near-copy of e1 once t is taken out), e3 (unrelated), and a
    two-column effect (v1, v2) one of whose directions is e3."""
    n, n_groups = 4000, 4
    t = rng.normal(size=n)
    s = rng.normal(size=n)
    e1 = s + 3.0 * t  # raw cosine with e2 is high either way; what counts is the part t leaves
    e2 = 0.95 * s + np.sqrt(1 - 0.95**2) * rng.normal(size=n) - 2.0 * t
    e3 = rng.normal(size=n)
    e4 = 2.0 * t + 0.1 * rng.normal(size=n)  # nearly all t: its residual is unrelated to e1's
    v1 = e3 + 0.3 * rng.normal(size=n)
    v2 = rng.normal(size=n)
    x = np.column_stack([t, e1, e2, e3, e4, v1, v2])
    group = np.repeat(np.arange(n_groups), n // n_groups)
    names = ["t", "e1", "e2", "e3", "e4", "v1", "v2"]
    return GroupSums.build(x, rng.normal(size=n), np.ones(n), group, n_groups, names)


def test_effects_stand_for_each_other_by_the_part_the_always_columns_leave() -> None:
    sums = _sums(np.random.default_rng(0))
    sets = [("e1",), ("e2",), ("e3",), ("e4",), ("v1", "v2")]
    stands = sets_standing_for(sums, np.ones(4), ["t"], sets)
    assert stands.shape == (5, 5) and np.array_equal(stands, stands.T) and stands.diagonal().all()
    assert stands[0, 1]  # e1 and e2 share ~90 % of their residual variance
    assert not stands[0, 3]  # e4 correlates with e1 only through t
    assert stands[2, 4]  # the two-column effect explains e3 in its best direction
    assert not stands[0, 2] and not stands[0, 4]
    # without t taken out, e1 and e4 would look alike: the rule is on the residualized columns
    assert sets_standing_for(sums, np.ones(4), [], sets)[0, 3]


def test_a_split_vote_between_effects_standing_for_each_other_counts_for_both() -> None:
    sums = _sums(np.random.default_rng(1))
    names = ["e1", "e2", "e3"]
    stands = sets_standing_for(sums, np.ones(4), ["t"], [("e1",), ("e2",), ("e3",)])
    picks = (("e1",), ("e2",), ("e1",), ("e2",), ("e3",), ())
    stab = Stability({"e1": 2 / 6, "e2": 2 / 6, "e3": 1 / 6}, PI_MIN, 5 / 6, 6, 3, picks)
    shares = represented_shares(stab, names, stands)
    assert shares == {"e1": 4 / 6, "e2": 4 / 6, "e3": 1 / 6}
    assert not stab.stable("e1") and shares["e1"] > stab.threshold  # neither alone in most halves; together yes


def test_only_a_split_vote_makes_an_effect_eligible_through_another() -> None:
    """Eligible: stable on its own; or represented by most halves while no effect standing for it is stable (a
    vote split between near-copies). An effect in a stable one's span is tested through that one."""
    names = ["own", "inside", "a", "b", "lone"]
    stands = np.eye(5, dtype=bool)
    stands[0, 1] = stands[1, 0] = True  # "inside" lies in "own"'s span
    stands[2, 3] = stands[3, 2] = True  # "a" and "b" carry one signal
    stab = Stability({"own": 1.0, "inside": 0.0, "a": 0.5, "b": 0.5, "lone": 0.3}, PI_MIN, 2.0, 6, 5)
    represented = {"own": 1.0, "inside": 1.0, "a": 1.0, "b": 1.0, "lone": 0.3}
    assert split_vote_eligible(stab, names, stands, represented) == {"own", "a", "b"}


def test_a_candidate_acting_on_one_flight_is_not_testable() -> None:
    cluster = np.array([0, 0, 1, 1, 2, 2])
    acts = np.zeros((6, 4), dtype=bool)
    acts[0, 0] = acts[1, 2] = True  # two logs, one flight
    assert not can_be_tested(acts, cluster)
    acts[4, 1] = True  # a second flight
    assert can_be_tested(acts, cluster)
    assert not can_be_tested(np.zeros((6, 4), dtype=bool), cluster)
    assert can_be_tested(acts, None)  # without flights, groups are the units
