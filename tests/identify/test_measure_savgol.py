"""The measurement's Savitzky-Golay filter through its operator built once per window
(:func:`proxplan.identify.measure._savgol`) is scipy's ``savgol_filter(..., mode="interp")``: the interior the
same floats, the edges (one least-squares fit rounded once instead of per call) equal to rounding."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import savgol_filter

from proxplan.identify.measure import _savgol

# the edges' largest difference seen, relative to the output's largest magnitude, was 3.6e-15 (a few ulps of
# the fit); the bound leaves 280x of room and still fails on any edge fitted differently
EDGE_REL_TOL = 1e-12


# (window, stretch shape): a window never longer than its stretch (measure._window_samples)
CASES = [(w, shape) for w in (3, 5, 15) for shape in [(3,), (5,), (16,), (16, 4), (401, 3)] if w <= shape[0]]


@pytest.mark.parametrize("deriv", [0, 1])
@pytest.mark.parametrize(("w", "shape"), CASES)
def test_the_operator_filters_as_scipy_does(deriv, w, shape):
    n = shape[0]
    x = np.random.default_rng(n * 100 + w * 10 + deriv).normal(size=shape) * 10.0
    dt_s = 0.0099  # not a round step: the derivative scales with it
    want = savgol_filter(x, w, 2, deriv=deriv, delta=dt_s, axis=0, mode="interp")
    got = _savgol(x, w, 2, deriv, dt_s)
    h = w // 2
    assert got.shape == want.shape
    assert np.array_equal(got[h : n - h], want[h : n - h])
    assert np.max(np.abs(got - want)) <= EDGE_REL_TOL * np.max(np.abs(want))


def test_a_smoothed_value_is_the_same_for_any_step_and_a_derivative_scales_with_it():
    x = np.random.default_rng(1).normal(size=(40, 2))
    assert np.array_equal(_savgol(x, 7, 2, 0, 0.01), _savgol(x, 7, 2, 0, 0.02))
    assert np.allclose(_savgol(x, 7, 2, 1, 0.01), 2.0 * _savgol(x, 7, 2, 1, 0.02), rtol=1e-12, atol=0.0)
