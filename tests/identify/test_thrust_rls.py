"""Seed 001: per-sample thrust coefficient, LS of (S1-25), RLS (S1-28..30) with forgetting."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.identify.thrust_rls import fit_ls, rls, thrust_samples
from proxplan.physics import AIR_DENSITY_KGPM3, BUILTIN_VEHICLES, GRAVITY_MPS2


def test_hover_thrust_coefficient_matches_k1() -> None:
    veh = BUILTIN_VEHICLES["large-quad"]
    n = 10
    s = thrust_samples(veh, np.tile([0, 0, 0, 1.0], (n, 1)), np.tile([0, 0, GRAVITY_MPS2], (n, 1)),
                       np.zeros((n, 3)), np.full((n, 4), veh.hover_thrust_per_rotor_N))  # fmt: skip
    p = veh.propeller
    expected = p.k1_Ns2prad2 / (AIR_DENSITY_KGPM3 * p.disk_area_m2 * p.radius_m**2)  # T = C_T rho A (omega R)^2
    np.testing.assert_allclose(s.c_t, expected, rtol=1e-9)
    assert np.all(s.regressors[:, 0] == 1.0) and np.all(s.regressors[:, 2] == 0.0)  # no advance ratio


def test_ls_and_rls_recover_parameters() -> None:
    rng = np.random.default_rng(3)
    x = np.column_stack([np.ones(2000), rng.normal(size=(2000, 5))])
    theta = np.array([0.013, -0.02, 0.01, 0.001, 0.002, 0.05])
    y = x @ theta + rng.normal(0, 1e-4, 2000)
    fit = fit_ls(x, y)
    np.testing.assert_allclose(fit.theta, theta, atol=5 * fit.std.max() + 1e-6)
    assert fit.r2 > 0.99
    hist = rls(x, y, forgetting=1.0)
    np.testing.assert_allclose(hist[-1], fit.theta, atol=1e-5)


def test_forgetting_factor_tracks_a_change() -> None:
    rng = np.random.default_rng(4)
    x = np.column_stack([np.ones(2000), rng.normal(size=2000)])
    theta = np.where(np.arange(2000)[:, None] < 1000, [1.0, 2.0], [1.5, 2.0])
    y = np.sum(x * theta, axis=1)
    with_forget = rls(x, y, forgetting=0.98)
    no_forget = rls(x, y, forgetting=1.0)
    assert with_forget[-1, 0] == pytest.approx(1.5, abs=1e-3)
    assert abs(no_forget[-1, 0] - 1.5) > 0.1  # plain RLS averages over both halves
    with pytest.raises(ValueError):
        rls(x, y, forgetting=0.0)
