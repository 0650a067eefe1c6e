"""A candidate whose held-out change lies on essentially one flight is reported as not testable by these flights
(identify.heldout_select.GainTest.one_flight, effective_units; identify.pipeline.IdentifyResult.one_flight)."""

from __future__ import annotations

import numpy as np

from proxplan.identify.heldout_select import effective_units, ratio_test
from proxplan.identify.pipeline import _one_flight_line


def test_kish_effective_units() -> None:
    assert effective_units(np.ones(4)) == 4.0
    assert effective_units(np.array([5.0, 0.0, 0.0])) == 1.0
    assert effective_units(np.zeros(3)) == 0.0
    assert 1.0 < effective_units(np.array([27759.0, 6.7, 5.9])) < 1.001  # block 18000's draw 15 (docs/identify.md)


def test_a_change_on_one_flight_is_reported_not_testable() -> None:
    # the figures of block 18000's draw 15: 99.9 % of the change on one flight, which it does not carry over to
    test = ratio_test(np.array([2.34, 14.0, -7090.0]), np.array([6.7, 5.9, 27759.0]), np.full(3, 1e4), 1)
    assert not test.passed and test.one_flight and not test.undecided
    doc = test.to_json()
    assert doc["one_flight"] is True and doc["effective_flights"] < 1.01
    line = _one_flight_line("near_field", doc)
    assert "mostly on one of them" in line and "of 3, under two" in line and "cannot judge it" in line


def test_spread_exposure_or_a_pass_is_not_one_flight() -> None:
    spread = ratio_test(np.array([1.0, -2.0, 0.5]), np.array([10.0, 12.0, 9.0]), np.full(3, 1e3), 1)
    assert not spread.passed and not spread.one_flight and spread.effective_flights > 2.5
    strong = ratio_test(np.array([10.0, 0.1, 0.11]), np.array([10.0, 0.1, 0.1]), np.full(3, 1e3), 1)
    assert not strong.one_flight  # whatever the exposure, a candidate that passes is kept, not "not testable"
    nowhere = ratio_test(np.zeros(0), np.zeros(0), np.zeros(0), 1)
    assert not nowhere.one_flight  # acts on no held-out flight: nothing to fly again


def test_a_candidate_acting_on_one_flight_is_reported_with_what_to_do() -> None:
    # no test at all (can_be_tested), but the user must hear that one flight holds it (stop 60; until stop 59
    # it was not reported, e.g. benchmark draw 19001's side kernel, chosen in every half-sample)
    single = ratio_test(np.array([3.0]), np.array([3.0]), np.array([10.0]), 1)
    assert not single.passed and single.one_flight and single.n_groups == 1
    line = _one_flight_line("force_z_N*side_g1L_e4L_1", single.to_json())
    assert "acts on one held-out flight only" in line and "fly that situation in more flights" in line
