"""The held-out gain test (identify.heldout_select.gain_test, derived in identify.crossval's docstring): the error
a candidate removes on each held-out flight per unit of what it changes there, pooled over the flights."""

from __future__ import annotations

import numpy as np

from proxplan.identify.crossval import GroupSums, Ridge, heldout_fit, plan_groups
from proxplan.identify.effect_selection import _rival_note
from proxplan.identify.heldout_select import Candidate, gain_test, heldout_forward

EXPOSURE = (2.0, 1.0, 0.5, 0.25)  # how much of the effect each flight holds (its column's scale), -


def _data(rng: np.random.Generator, n_flights: int, *, effect: float, copy_noise: float = 1.0):
    """Per flight 4000 samples: ``t`` (always fitted), ``x`` (the effect's column, scaled by the flight's
    exposure), ``x2`` (x plus ``copy_noise`` of independent noise), ``u`` (unrelated); y = t + effect x +
    noise + a per-flight misfit along t's direction the model does not have."""
    n = 4000
    rows, flights = [], []
    for f in range(n_flights):
        t, x, u = rng.normal(size=n), EXPOSURE[f % len(EXPOSURE)] * rng.normal(size=n), rng.normal(size=n)
        x2 = x + copy_noise * rng.normal(size=n)
        y = t + effect * x + rng.normal(size=n) + rng.normal() * np.tanh(t)
        rows.append(np.column_stack([t, x, x2, u, y]))
        flights.append(np.full(n, f))
    data = np.vstack(rows)
    group = np.concatenate(flights)
    sums = GroupSums.build(data[:, :4], data[:, 4], np.ones(len(data)), group, n_flights, ["t", "x", "x2", "u"])
    plan = plan_groups([(f"f{k}", "v") for k in range(n_flights)], [])
    return sums, plan, Ridge(np.zeros(4), np.zeros(4))


def _test(sums: GroupSums, plan, ridge: Ridge, name: str):
    base = sums.index(["t"])
    without = heldout_fit(sums, base, plan, ridge, 1.0)
    with_ = heldout_fit(sums, np.concatenate([base, sums.index([name])]), plan, ridge, 1.0)
    return gain_test(sums, without, with_, 1, cluster=plan.cluster)


def test_an_effect_that_carries_over_passes_whatever_each_flight_holds_of_it() -> None:
    """An effect over four flights whose exposure spans 8x (its share of a flight's error from 14 % down to
    0.25 %): it removes what it changes on every flight (R near 1) and passes (t 4.5 to 23 over 20 seeds,
    against 2.35); an unrelated column removes minus what it changes (R near -1)."""
    sums, plan, ridge = _data(np.random.default_rng(0), 4, effect=0.2)
    real = _test(sums, plan, ridge, "x")
    assert real.passed and 0.5 < real.mean < 1.5 and real.n_groups == 4
    noise = _test(sums, plan, ridge, "u")
    assert not noise.passed and noise.mean < 0


def test_on_data_without_the_effect_the_test_passes_at_most_its_level() -> None:
    """The family-wise level: 200 data sets without any effect (3 to 6 flights, a per-flight misfit the model
    lacks), one candidate each: at level 0.05 about 10 would pass if the test were exact; the derivation makes
    it conservative (a change fitted to noise costs its own size), so fewer than 10 may."""
    rng = np.random.default_rng(1)
    passed = sum(_test(*_data(rng, 3 + k % 4, effect=0.0), "u").passed for k in range(200))
    assert passed <= 10, passed


def test_two_effects_the_flights_cannot_tell_apart_are_named_as_rivals() -> None:
    """x and a near copy of it (x2, 1 % noise) both pass; the forward pass keeps one and names the other as a
    rival it was not shown better than, and the reasons name each other."""
    sums, plan, ridge = _data(np.random.default_rng(2), 5, effect=0.2, copy_noise=0.01)
    out = heldout_forward(sums, ["t"], [Candidate("x", ("x",)), Candidate("x2", ("x2",))], plan, ridge, 1.0,
                          max_terms=2)  # fmt: skip
    assert len(out.chosen) == 1
    kept = out.chosen[0]
    other = {"x": "x2", "x2": "x"}[kept]
    assert other in out.rivals[kept]
    assert f"not shown better than {other}" in _rival_note(kept, out.rivals)
    assert f"cannot tell it from the kept {kept}" in _rival_note(other, out.rivals)
