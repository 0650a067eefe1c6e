"""Which vehicle-parameter groups keep their recalibration at the prior start (identify.earned): a group is held
at its prior when, given the others, it predicts the flights held out worse than without it (R < 0)."""

from __future__ import annotations

import numpy as np

from proxplan.identify.calibrate import STACK_PARAMETER
from proxplan.identify.crossval import GroupSums, Ridge, plan_groups
from proxplan.identify.earned import backward_by_heldout_error, parameter_group


def _data(rng: np.random.Generator, n_flights: int, n: int = 3000):
    """Per flight ``n`` samples of y = s + 0.2 x + c_f z + noise: ``s`` the thrust scales' column (always
    fitted), ``x`` a parameter step that carries over (the same 0.2 on every flight), ``z`` one whose size and
    sign change from flight to flight (c_f ~ N(0, 0.3^2): what a recalibration absorbs of an effect the model
    lacks, and cannot carry to a new flight), ``u`` unrelated."""
    rows, flights = [], []
    for f in range(n_flights):
        s, x, z, u = (rng.normal(size=n) for _ in range(4))
        y = s + 0.2 * x + 0.3 * rng.normal() * z + rng.normal(size=n)
        rows.append(np.column_stack([s, x, z, u, y]))
        flights.append(np.full(n, f))
    d = np.vstack(rows)
    sums = GroupSums.build(d[:, :4], d[:, 4], np.ones(len(d)), np.concatenate(flights), n_flights, ["s", "x", "z", "u"])
    return sums, plan_groups([(f"f{k}", "v") for k in range(n_flights)], []), Ridge(np.zeros(4), np.zeros(4))


def test_a_step_that_carries_over_is_kept_and_one_that_does_not_is_mostly_held() -> None:
    """40 data sets of 3 to 6 flights: the carrying group is kept in every one; the flight-to-flight one and the
    unrelated one are each held in most (measured 29 and 32 of 40: a point-estimate choice keeps a useless step
    whenever its held-out gain happens to be positive, about one set in four here)."""
    kept = {"x": 0, "z": 0, "u": 0}
    for seed in range(40):
        sums, plan, ridge = _data(np.random.default_rng(seed), 3 + seed % 4)
        chosen, rounds = backward_by_heldout_error(sums, plan, ridge, 1.0, ["s"], {g: [g] for g in kept})
        assert set(rounds[0]) == set(kept)
        for g in chosen:
            kept[g] += 1
    assert kept["x"] == 40
    assert kept["z"] <= 20 and kept["u"] <= 20, kept


def test_groups_are_named_by_role() -> None:
    assert parameter_group("large-quad.c_ax") == "large-quad as a source"
    assert parameter_group("large-quad.z0_m") == "large-quad as a source"
    assert parameter_group("crazyflie-2.1.b_v") == "crazyflie-2.1 as a target"
    assert parameter_group(STACK_PARAMETER) == "stack shielding"
