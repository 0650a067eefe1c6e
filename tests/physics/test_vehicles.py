"""Built-in vehicles: S0 Table I numbers, (S0-14) rotor layout, sane derived values."""

import numpy as np
import pytest

from proxplan.physics.builtin_vehicles import BUILTIN_VEHICLES, LARGE_QUAD, SMALL_QUAD


def test_builtin_names_are_the_contract():
    assert set(BUILTIN_VEHICLES) == {"small-quad", "large-quad", "crazyflie-2.1", "crazyflie-parrot"}


def test_table_one_values():
    assert SMALL_QUAD.propeller.diameter_m == 0.0508 and LARGE_QUAD.propeller.diameter_m == 0.2032
    assert SMALL_QUAD.arm_length_m == 0.0585 and LARGE_QUAD.arm_length_m == 0.165
    assert SMALL_QUAD.mass_kg == 0.145 and LARGE_QUAD.mass_kg == 0.650
    assert SMALL_QUAD.max_thrust_N == 4.6 and LARGE_QUAD.max_thrust_N == 27.0
    assert (SMALL_QUAD.downwash.c_ax, SMALL_QUAD.downwash.z0_m, SMALL_QUAD.downwash.c_rad) == (4.672, 0.033, 60.808)
    assert (LARGE_QUAD.downwash.c_ax, LARGE_QUAD.downwash.z0_m, LARGE_QUAD.downwash.c_rad) == (4.886, 0.110, 24.936)


def test_rotor_layout_follows_s0_14():
    pos = LARGE_QUAD.rotor_positions_m
    signs = np.sign(pos[:, :2])
    np.testing.assert_array_equal(signs, [[1, -1], [-1, -1], [-1, 1], [1, 1]])
    np.testing.assert_allclose(np.linalg.norm(pos, axis=1), LARGE_QUAD.arm_length_m)


@pytest.mark.parametrize("vehicle", list(BUILTIN_VEHICLES.values()), ids=list(BUILTIN_VEHICLES))
def test_derived_values_are_physical(vehicle):
    assert vehicle.size_m == 2 * vehicle.arm_length_m
    assert 1.3 < vehicle.max_thrust_N / vehicle.weight_N < 6.0  # can hover with margin
    omega_hover = vehicle.hover_omega_sq_rad2ps2**0.5
    tip_speed = omega_hover * vehicle.propeller.radius_m
    assert 30.0 < tip_speed < 250.0, tip_speed  # subsonic, realistic hover tip speed, m/s
    jxx, jyy, jzz = vehicle.inertia_diag_kgm2
    assert jzz > jxx > 0 and jxx == jyy
    d = vehicle.to_dict()
    assert d["propeller"]["k1_Ns2prad2"] > 0 and d["size_L_m"] == vehicle.size_m
