"""Calibration: bounded least squares with Jacobian uncertainty; vehicle parameters via replace."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.identify.calibrate import ParamSpec, apply_vehicle_parameters, fit_parameters
from proxplan.physics import BUILTIN_VEHICLES, disturbance_wrench

SQ = BUILTIN_VEHICLES["small-quad"]


def test_recovers_downwash_and_b_v_from_model_forces() -> None:
    truth = apply_vehicle_parameters(SQ, c_ax=6.0, c_rad=45.0, b_v=2.0 * SQ.b_v)
    rng = np.random.default_rng(0)
    offsets = np.column_stack([rng.uniform(-0.3, 0.3, 400), rng.uniform(-0.3, 0.3, 400), -rng.uniform(0.4, 1.5, 400)])
    y = disturbance_wrench(truth, truth, offsets).force_N[:, 2]

    def residual(theta: np.ndarray) -> np.ndarray:
        v = apply_vehicle_parameters(SQ, c_ax=theta[0], c_rad=theta[1], b_v=theta[2] * 1e-9)
        return disturbance_wrench(v, v, offsets).force_N[:, 2] - y

    specs = [ParamSpec("c_ax", SQ.downwash.c_ax, 1.0, 20.0), ParamSpec("c_rad", SQ.downwash.c_rad, 5.0, 300.0),
             ParamSpec("b_v_e9", SQ.b_v * 1e9, 0.01, 100.0)]  # fmt: skip
    res = fit_parameters(residual, specs)
    assert res.success
    np.testing.assert_allclose(res.values, [6.0, 45.0, 2e9 * SQ.b_v], rtol=1e-3)
    assert res.rmse < 1e-6


def test_uncertainty_matches_noise_level() -> None:
    rng = np.random.default_rng(1)
    x = np.linspace(0.0, 1.0, 500)
    sigma = 0.01
    y = 2.0 * np.exp(-3.0 * x) + rng.normal(0, sigma, x.size)
    res = fit_parameters(
        lambda th: th[0] * np.exp(-th[1] * x) - y, [ParamSpec("a", 1.0, 0.1, 10.0), ParamSpec("k", 1.0, 0.1, 10.0)]
    )
    assert res.values[0] == pytest.approx(2.0, abs=4 * res.std[0])
    assert res.values[1] == pytest.approx(3.0, abs=4 * res.std[1])
    assert 0.0 < res.std[0] < 0.05 and res.rmse == pytest.approx(sigma, rel=0.15)


def test_apply_vehicle_parameters() -> None:
    v = apply_vehicle_parameters(SQ, z0_m=0.05, b_v=1e-8)
    assert v.downwash.z0_m == 0.05 and v.downwash.c_ax == SQ.downwash.c_ax and v.b_v == 1e-8
    assert SQ.downwash.z0_m != 0.05  # original untouched (frozen dataclass)
    with pytest.raises(ValueError):
        apply_vehicle_parameters(SQ, mass_kg=1.0)
