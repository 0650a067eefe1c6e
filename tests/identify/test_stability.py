"""Stability selection's half-samples and the in-fold eligibility (proxplan.identify.stability)."""

from __future__ import annotations

import numpy as np

from proxplan.identify.crossval import plan_groups
from proxplan.identify.stability import fold_eligibility, fold_half_samples, half_samples


def _plan(n_train: int, n_valid: int = 0):
    fit = [(f"f{k}", v) for k in range(n_train) for v in ("a", "b")]
    valid = [(f"v{k}", v) for k in range(n_valid) for v in ("a", "b")]
    return plan_groups(fit, valid)


def test_fold_halves_never_weigh_the_held_out_flight_nor_validation() -> None:
    plan = _plan(6, 1)
    folds = fold_half_samples(plan, 0)
    train_clusters = set(np.unique(plan.cluster[~plan.held_out_only]).tolist())
    assert set(folds) == train_clusters
    for c, halves in folds.items():
        assert halves, c
        for w in halves:
            assert not np.any(w[plan.cluster == c]), c  # the held-out flight is in no half
            assert not np.any(w[plan.held_out_only]), c  # nor a validation flight
        # complementary pairs: each pair covers the other train flights exactly once
        for a, b in zip(halves[::2], halves[1::2]):
            assert np.all((a + b)[(plan.cluster != c) & ~plan.held_out_only] == 1.0)
    assert len(half_samples(plan, 0)) > len(folds[0])  # fewer halves in a fold (FOLD_PAIRS)


def test_fold_eligibility_masks_only_the_flights_whose_fold_did_not_choose_it() -> None:
    plan = _plan(3, 1)
    without = {0: {"x", "y"}, 1: {"y"}, 2: {"x", "y"}}
    mask = fold_eligibility(plan, without, ["x", "y", "z"])
    assert np.array_equal(mask["x"], plan.cluster != 1)  # validation groups (cluster 3) keep True
    assert mask["y"].all()
    assert np.array_equal(mask["z"], plan.held_out_only)  # chosen in no fold: only validation flights count
