"""Velocity field (S0-1, S0-2) in both named forms."""

import numpy as np
import pytest

from proxplan.physics.builtin_vehicles import LARGE_QUAD, SMALL_QUAD
from proxplan.physics.velocity_field import centreline_speed_mps, downwash_speed_mps, induced_velocity_mps


def test_inverse_z_form_decays_as_one_over_z_and_printed_as_one_over_sqrt_z():
    z0 = SMALL_QUAD.downwash.z0_m
    dz = np.array([1.0, 2.0]) + z0
    inv = centreline_speed_mps(SMALL_QUAD, dz, form="inverse-z")
    printed = centreline_speed_mps(SMALL_QUAD, dz, form="printed")
    assert inv[0] / inv[1] == pytest.approx(2.0)
    assert printed[0] / printed[1] == pytest.approx(np.sqrt(2.0))


def test_centreline_value_from_momentum_theory():
    v_i = induced_velocity_mps(LARGE_QUAD)
    thrust = LARGE_QUAD.hover_thrust_per_rotor_N
    assert v_i == pytest.approx(np.sqrt(thrust / (2 * 1.225 * np.pi * 0.1016**2)))
    dz = 2.0
    expected = v_i * LARGE_QUAD.downwash.c_ax * LARGE_QUAD.size_m / (dz - LARGE_QUAD.downwash.z0_m)
    assert centreline_speed_mps(LARGE_QUAD, dz) == pytest.approx(expected)


def test_gaussian_profile_and_linear_spread():
    dz = np.array([1.0, 2.0])
    axial = dz - SMALL_QUAD.downwash.z0_m
    r_half = axial * np.sqrt(np.log(2.0) / SMALL_QUAD.downwash.c_rad)  # half-speed radius grows with dz
    ratio = downwash_speed_mps(SMALL_QUAD, dz, r_half**2) / centreline_speed_mps(SMALL_QUAD, dz)
    np.testing.assert_allclose(ratio, 0.5)
    assert r_half[1] > r_half[0]


def test_no_flow_above_the_source_and_finite_near_field():
    assert downwash_speed_mps(SMALL_QUAD, np.array([-0.1, 0.0]), np.zeros(2)).tolist() == [0.0, 0.0]
    near = downwash_speed_mps(SMALL_QUAD, np.array([1e-3, 0.01, 0.03]), np.zeros(3))
    assert np.all(np.isfinite(near)) and np.all(near > 0)
    with pytest.raises(ValueError, match="unknown field form"):
        centreline_speed_mps(SMALL_QUAD, 1.0, form="sqrt")
