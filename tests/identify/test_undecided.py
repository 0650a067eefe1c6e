"""A term every held-out flight gained from, short of the test's multiple, is reported as not decided by the
flights (identify.heldout_select.GainTest.undecided, identify.pipeline.IdentifyResult.undecided)."""

from __future__ import annotations

import numpy as np

from proxplan.identify.heldout_select import critical_z, ratio_test
from proxplan.identify.pipeline import _undecided_line


def _test(ratios: list[float], m: int, energy: list[float] | None = None):
    """ratio_test on per-flight gains = ratio x energy (energy 1 each unless given), error without = 10."""
    e = np.ones(len(ratios)) if energy is None else np.asarray(energy, dtype=float)
    return ratio_test(np.asarray(ratios) * e, e, np.full(len(ratios), 10.0), m)


def test_every_flight_gained_but_three_flights_cannot_pass() -> None:
    test = _test([0.10, 0.50, 0.30], 2)  # t = 2.6 over 3 flights
    assert test.z == critical_z(2, 2) and 4.0 < test.z < 5.0  # Student's t with 2 degrees of freedom
    assert not test.passed and test.undecided
    doc = test.to_json()
    assert doc["groups_improved"] == 3 == doc["n_groups"] and doc["undecided"] is True
    line = _undecided_line("force_z_N*thrust_kin_jet_N", doc)
    assert "every one of the 3 held-out flights gained" in line and f"t > {test.z:.2f}" in line


def test_a_flight_that_lost_or_a_passing_test_is_not_undecided() -> None:
    mixed = _test([0.20, -0.05, 0.30], 2)
    assert not mixed.passed and not mixed.undecided and mixed.to_json()["groups_improved"] == 2
    strong = _test([0.30, 0.31, 0.32, 0.30, 0.33, 0.31], 1)
    assert strong.passed and not strong.undecided
    one = _test([0.3], 1)  # one flight: no test, nothing to decide
    assert not one.undecided


def test_the_ratio_is_pooled_by_energy_so_unequal_exposure_is_not_spread() -> None:
    """Three flights whose predictions all hold (gain = energy: the candidate removes what it changes) pass
    however unequal their exposure; the same gains as plain per-flight means would spread from 0.03 to 3."""
    energy = [3.0, 0.1, 0.03]
    held = _test([0.98, 1.01, 0.97], 3, energy)
    assert held.passed and abs(held.mean - (0.98 * 3 + 1.01 * 0.1 + 0.97 * 0.03) / 3.13) < 1e-12
    wrong = _test([-1.0, -0.9, -1.1], 1, energy)  # a change fitted to noise: removes minus what it changes
    assert not wrong.passed and wrong.mean < 0
