"""Library effects read as the measurement reads the wrench (proxplan.identify.reading, issue 35): at the
selection's sparse rows, a column plus its correction is the full-rate effect smoothed by the measurement's
own filter and read at the rows, also for an effect that acts late; while a shape is fitted, the scaled
correction is exact for a change of strength."""

from __future__ import annotations

import numpy as np

from proxplan.identify.data import Model, Unit, unit_inputs
from proxplan.identify.measure import MeasureOptions, smoothed_on_clock
from proxplan.identify.noise import stacked
from proxplan.identify.reading import MeasurementReading
from proxplan.physics import BUILTIN_VEHICLES, LAG_PARAM, Effect, effect_wrench

TYPE = "crazyflie-2.1"
OPTIONS = MeasureOptions(window_s=0.15)


def _unit(t: np.ndarray) -> Unit:
    """A vehicle 0.15-0.45 m under another that sweeps across it at up to 1.9 m/s (its jet crossed in ~0.1 s)."""
    n = len(t)
    # p_target - p_source, m
    offsets = np.column_stack([-0.6 * np.sin(3.2 * t), 0.02 + 0 * t, -0.3 - 0.15 * np.sin(1.1 * t)])
    zeros = np.zeros((n, 3))
    veh = BUILTIN_VEHICLES[TYPE]
    return Unit("f", "train", "low", TYPE, t, zeros, np.full(n, 1.0), np.full(n, veh.weight_N), (TYPE,), (offsets,),
                zeros, zeros)  # fmt: skip


def _reading(unit: Unit, rows: np.ndarray, model: Model) -> MeasurementReading:
    return MeasurementReading([unit], rows, np.ones((len(rows), 4)), np.ones(len(rows)), model, OPTIONS)


def _full(effect: Effect, unit: Unit, model: Model) -> np.ndarray:
    return stacked(*effect_wrench(effect, unit_inputs(unit, model)))


def test_a_column_plus_its_correction_is_the_smoothed_effect_at_the_rows() -> None:
    t = 0.01 * np.arange(1200)
    unit, model = _unit(t), Model(vehicles={TYPE: BUILTIN_VEHICLES[TYPE]})
    rows = np.sort(np.random.default_rng(3).choice(np.arange(100, 1100), 200, replace=False))
    reading = _reading(unit, rows, model)
    effect = Effect("thrust_quadratic", {"b_q_rel_spm": 0.4})
    full = _full(effect, unit, model)
    smoothed = smoothed_on_clock(t, full, options=OPTIONS)
    assert np.max(np.abs(smoothed - full)) > 0.2 * np.max(np.abs(full))  # the window flattens this effect
    read = full[rows] + reading.correction(effect, 0.0, full[rows])
    np.testing.assert_allclose(read, smoothed[rows], rtol=0, atol=1e-6 * np.max(np.abs(full)))
    # late by 0.23 s: the smoothed effect of the state 0.23 s earlier, an independent path (the effect's own lag)
    late = _full(Effect("thrust_quadratic", {"b_q_rel_spm": 0.4, LAG_PARAM: 0.23}), unit, model)
    late_smoothed = smoothed_on_clock(t, late, options=OPTIONS)
    read_late = late[rows] + reading.correction(effect, 0.23, late[rows])
    err = np.max(np.abs(read_late - late_smoothed[rows]))
    assert err < 0.02 * np.max(np.abs(full)), err


def test_while_a_shape_is_fitted_the_scaled_correction_is_exact_for_a_change_of_strength() -> None:
    t = 0.01 * np.arange(800)
    unit, model = _unit(t), Model(vehicles={TYPE: BUILTIN_VEHICLES[TYPE]})
    rows = np.arange(50, 750, 3)
    reading = _reading(unit, rows, model)
    first = Effect("near_field", {"amplitude": 1.0, "decay_L": 3.0})
    reading.correction(first, 0.0, _full(first, unit, model)[rows])  # the exact one, at these parameters
    stronger = Effect("near_field", {"amplitude": 2.5, "decay_L": 3.0})
    cols = _full(stronger, unit, model)[rows]
    scaled = reading.correction(stronger, 0.0, cols, exact=False)
    exact = _reading(unit, rows, model).correction(stronger, 0.0, cols)
    np.testing.assert_allclose(scaled, exact, rtol=0, atol=1e-5 * np.max(np.abs(exact)))
    # another shape is only approximated (first order); the exact call gives its own
    wider = Effect("near_field", {"amplitude": 1.0, "decay_L": 6.0})
    cols_w = _full(wider, unit, model)[rows]
    approx = reading.correction(wider, 0.0, cols_w, exact=False)
    own = reading.correction(wider, 0.0, cols_w)
    assert np.max(np.abs(approx - own)) > 1e-3 * np.max(np.abs(own))


def test_the_filter_never_crosses_a_gap_in_the_clock() -> None:
    t = np.concatenate([0.01 * np.arange(100), 5.0 + 0.01 * np.arange(100)])
    x = np.concatenate([np.zeros(100), np.ones(100)])[:, None]
    np.testing.assert_allclose(smoothed_on_clock(t, x, options=OPTIONS), x, atol=1e-12)
