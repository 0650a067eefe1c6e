"""The residual's split that evaluate and identify report (proxplan.identify.spread.BandAccumulator): below and
above 1 Hz, and the part that is one constant per vehicle log."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.identify.spread import BAND_HZ, BandAccumulator, slow_part

GRAMS_PER_N = 1000.0 / 9.80665


def test_a_constant_per_log_and_a_fast_wobble_are_told_apart() -> None:
    """Two logs, each a constant offset (10 and -20 mN) plus a 5 Hz wobble of 5 mN amplitude: the constant part
    is the RMS of the two offsets exactly, the slow part is the offsets (the low-pass keeps a constant and
    removes 5 Hz), the fast part the wobble's RMS (5 mN / sqrt 2)."""
    t_s = np.arange(0.0, 20.0, 0.01)
    wobble_N = 0.005 * np.sin(2.0 * np.pi * 5.0 * t_s)
    assert 5.0 > 2.0 * BAND_HZ  # the wobble lies well above the split
    acc = BandAccumulator()
    for offset_N in (0.010, -0.020):
        residual = offset_N + wobble_N
        acc.add(residual, slow_part(residual, t_s), None)
    out = acc.to_json(GRAMS_PER_N)
    offsets_rms_N = np.sqrt((0.010**2 + 0.020**2) / 2.0)
    assert out["rmse_fz_constant_per_log_N"] == pytest.approx(offsets_rms_N, rel=1e-6)
    assert out["rmse_fz_constant_per_log_g"] == pytest.approx(offsets_rms_N * GRAMS_PER_N, rel=1e-6)
    assert out["rmse_fz_below_1Hz_N"] == pytest.approx(offsets_rms_N, rel=0.02)
    assert out["rmse_fz_above_1Hz_N"] == pytest.approx(0.005 / np.sqrt(2.0), rel=0.05)
    assert out["coverage_90"] is None and out["n_samples"] == 2 * len(t_s)


def test_a_log_with_no_offset_has_no_constant_part() -> None:
    """A zero-mean residual (a whole number of periods of a slow 0.5 Hz swing) has no constant part, though
    its slow part is large."""
    t_s = np.arange(0.0, 20.0, 0.01)
    residual = 0.01 * np.sin(2.0 * np.pi * 0.5 * t_s)
    acc = BandAccumulator()
    acc.add(residual, slow_part(residual, t_s), None)
    out = acc.to_json(GRAMS_PER_N)
    assert out["rmse_fz_constant_per_log_N"] < 1e-3 * out["rmse_fz_below_1Hz_N"]
    assert out["rmse_fz_below_1Hz_N"] > 0.005
