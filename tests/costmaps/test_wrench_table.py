"""Wrench table: interpolant error vs the direct model, numpy/CasADi agreement, extents, symmetry."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.costmaps.wrench_table import (
    USAGE_FLOOR,
    TableResolution,
    build_wrench_table,
    mirror_quadrant,
)
from proxplan.physics import BUILTIN_VEHICLES, VALIDITY_FACTOR_L, authority_usage, disturbance_wrench

SMALL, LARGE = BUILTIN_VEHICLES["small-quad"], BUILTIN_VEHICLES["large-quad"]
CF = BUILTIN_VEHICLES["crazyflie-2.1"]
PAIRS = [(SMALL, LARGE), (LARGE, CF), (CF, LARGE)]


@pytest.fixture(scope="module")
def tables():
    return {(s.name, t.name): build_wrench_table(s, t) for s, t in PAIRS}


def _random_offsets(table, rng, n, *, dz_hi=None, lateral=1.0):
    """Uniform random offsets (n, 3) inside the table (p_target - p_source, m)."""
    dz = rng.uniform(table.dz_m[0], table.dz_m[-1] if dz_hi is None else dz_hi, n)
    half = table.scale.half_width_m(dz)
    xi = rng.uniform(-lateral, lateral, (n, 2))
    return np.column_stack([xi[:, 0] * half, xi[:, 1] * half, -dz])


@pytest.mark.parametrize("pair", [(s.name, t.name) for s, t in PAIRS])
def test_interpolant_error_below_two_percent_of_peak(tables, pair):
    source, target = BUILTIN_VEHICLES[pair[0]], BUILTIN_VEHICLES[pair[1]]
    table = tables[pair]
    rng = np.random.default_rng(7)
    # whole table, and the near-field part (dz < 10 L, inner half laterally) where gradients are steep
    offsets = np.vstack(
        [
            _random_offsets(table, rng, 4000),
            _random_offsets(table, rng, 4000, dz_hi=10 * source.size_m, lateral=0.5),
        ]
    )
    direct = disturbance_wrench(source, target, offsets)
    force, torque = table.wrench_numpy(offsets)
    peak_force = table.peak_abs_force_N
    peak_torque = max(np.abs(table.torque_x_Nm).max(), np.abs(table.torque_y_Nm).max())
    assert peak_force > 0 and peak_torque > 0
    assert np.abs(force[:, 2] - direct.force_N[:, 2]).max() < 0.02 * peak_force
    assert np.abs(torque[:, :2] - direct.torque_Nm[:, :2]).max() < 0.02 * peak_torque
    # the axial-flow model has no lateral force and no yaw torque; the table keeps them zero
    assert np.allclose(direct.force_N[:, :2], 0.0) and np.allclose(force[:, :2], 0.0)
    assert np.allclose(torque[:, 2], 0.0)


def test_casadi_function_matches_numpy_and_is_differentiable(tables):
    import casadi as ca

    table = tables[("small-quad", "large-quad")]
    fn = table.casadi_function()
    rng = np.random.default_rng(3)
    offsets = _random_offsets(table, rng, 200, dz_hi=2.0, lateral=0.6)
    force, torque = table.wrench_numpy(offsets)
    out = np.array(fn(offsets.T)).T  # (N, 3): F_z, tau_x, tau_y
    assert np.allclose(out[:, 0], force[:, 2], rtol=1e-9, atol=1e-12)
    assert np.allclose(out[:, 1:], torque[:, :2], rtol=1e-9, atol=1e-12)

    x = ca.MX.sym("x", 3)
    jac = ca.Function("wrench_jacobian", [x], [ca.jacobian(fn(x), x)])
    point = np.array([0.05, -0.03, -0.6])
    analytic = np.array(jac(point))
    step = 1e-6
    numeric = np.column_stack(
        [(np.array(fn(point + step * e)) - np.array(fn(point - step * e))).ravel() / (2 * step) for e in np.eye(3)]
    )
    assert np.all(np.isfinite(analytic))
    assert np.abs(analytic).max() > 0.0
    assert np.allclose(analytic, numeric, rtol=1e-4, atol=1e-6 * np.abs(analytic).max())


def test_extent_usage_below_floor_and_zero_outside(tables):
    table = tables[("small-quad", "large-quad")]
    assert table.boundary_usage < USAGE_FLOOR
    # just outside the lateral boundary the direct model's usage is below the floor too
    dz = np.linspace(table.dz_m[0], table.dz_m[-1], 25)
    half = table.scale.half_width_m(dz) * 1.02
    offsets = np.column_stack([half, np.zeros_like(dz), -dz])
    direct = disturbance_wrench(SMALL, LARGE, offsets)
    assert authority_usage(LARGE, direct.force_N, direct.torque_Nm).max() < USAGE_FLOOR
    force, torque = table.wrench_numpy(offsets)
    assert np.all(force == 0.0) and np.all(torque == 0.0)
    # above the source: no downwash
    force, _ = table.wrench_numpy(np.array([[0.0, 0.0, 0.3], [0.1, 0.0, 0.01]]))
    assert np.all(force == 0.0)


def test_invalid_zone_holds_first_layer_not_zero(tables):
    table = tables[("small-quad", "large-quad")]
    assert table.dz_m[0] == pytest.approx(VALIDITY_FACTOR_L * SMALL.size_m)
    near, _ = table.wrench_numpy(np.array([[0.02, 0.0, -0.5 * table.dz_m[0]]]))
    first, _ = table.wrench_numpy(np.array([[0.02, 0.0, -table.dz_m[0]]]))
    assert near[0, 2] < 0.0
    assert near[0, 2] == pytest.approx(first[0, 2])


def test_full_near_field_table_flags_invalid_layers():
    table = build_wrench_table(SMALL, CF, resolution=TableResolution(n_xy=15, n_dz=12, dz_min_m=0.0, dz_max_m=1.0))
    assert table.dz_m[0] == 0.0
    assert not table.valid[0] and table.valid[-1]
    assert np.array_equal(table.valid, table.dz_m > VALIDITY_FACTOR_L * SMALL.size_m)


def test_mirror_symmetry_matches_direct_model(tables):
    table = tables[("large-quad", "crazyflie-2.1")]
    k = 10
    i, j = 30, 27  # a node with xi > 0, eta > 0
    x, y = table.offset_x_m[i, k], table.offset_y_m[j, k]
    offsets = np.array([[sx * x, sy * y, -table.dz_m[k]] for sx in (1, -1) for sy in (1, -1)])
    direct = disturbance_wrench(LARGE, CF, offsets)
    ii = [i, table.xi.size - 1 - i]
    jj = [j, table.eta.size - 1 - j]
    stored = np.array(
        [[table.force_z_N[a, b, k], table.torque_x_Nm[a, b, k], table.torque_y_Nm[a, b, k]] for a in ii for b in jj]
    )
    expect = np.column_stack([direct.force_N[:, 2], direct.torque_Nm[:, 0], direct.torque_Nm[:, 1]])
    assert np.allclose(stored, expect, rtol=1e-10, atol=1e-14)
    assert np.abs(expect[:, 1]).max() > 0  # the check is not vacuous


def test_mirror_quadrant_signs():
    q = np.arange(6.0).reshape(2, 3) + 1.0
    full = mirror_quadrant(q, -1.0, 1.0)
    assert full.shape == (3, 5)
    assert full[1, 2] == q[0, 0]
    assert full[0, 2] == -q[1, 0]
    assert full[2, 0] == q[1, 2]


def test_resolution_rejects_bad_input():
    with pytest.raises(ValueError):
        TableResolution(n_xy=40)
    with pytest.raises(ValueError):
        TableResolution(dz_max_m=-1.0)
