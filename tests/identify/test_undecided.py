"""A term every held-out flight gained from, short of the test's multiple, is reported as not decided by the
flights (identify.heldout_select.GainTest.undecided, identify.pipeline.IdentifyResult.undecided)."""

from __future__ import annotations

import numpy as np

from proxplan.identify.heldout_select import critical_z, flight_test
from proxplan.identify.pipeline import _undecided_line


def test_every_flight_gained_but_three_flights_cannot_pass() -> None:
    gains = np.array([0.10, 0.50, 0.30])  # t = 2.6 over 3 flights
    test = flight_test(gains, 2, np.arange(3))
    assert test.z == critical_z(2, 2) and 4.0 < test.z < 5.0  # Student's t with 2 degrees of freedom
    assert not test.passed and test.undecided
    doc = test.to_json()
    assert doc["groups_improved"] == 3 == doc["n_groups"] and doc["undecided"] is True
    line = _undecided_line("force_z_N*thrust_kin_jet_N", doc)
    assert "every one of the 3 held-out flights gained" in line and f"t > {test.z:.2f}" in line


def test_a_flight_that_lost_or_a_passing_test_is_not_undecided() -> None:
    mixed = flight_test(np.array([0.20, -0.05, 0.30]), 2, np.arange(3))
    assert not mixed.passed and not mixed.undecided and mixed.to_json()["groups_improved"] == 2
    strong = flight_test(np.array([0.30, 0.31, 0.32, 0.30, 0.33, 0.31]), 1, np.arange(6))
    assert strong.passed and not strong.undecided
    one = flight_test(np.array([0.3]), 1, np.arange(1))  # one flight: no test, nothing to decide
    assert not one.undecided
