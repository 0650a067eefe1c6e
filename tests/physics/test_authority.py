"""Authority usage (DESIGN.md section 3) from the (S0-14) mixer."""

import numpy as np

from proxplan.physics import authority_usage, mixer_matrix, motor_thrusts_N
from proxplan.physics.builtin_vehicles import LARGE_QUAD, SMALL_QUAD


def test_no_disturbance_means_hover_thrust_and_zero_usage():
    f = motor_thrusts_N(LARGE_QUAD, np.zeros(3), np.zeros(3))
    np.testing.assert_allclose(f, LARGE_QUAD.hover_thrust_per_rotor_N)
    assert authority_usage(LARGE_QUAD, np.zeros((1, 3)), np.zeros((1, 3)))[0] == 0.0


def test_mixer_matches_s0_14():
    v = SMALL_QUAD
    f = np.array([1.0, 2.0, 3.0, 4.0])
    T, tx, ty, tz = mixer_matrix(v) @ f
    h = v.arm_length_m / np.sqrt(2)
    assert np.isclose(T, 10.0)
    assert np.isclose(tx, h * ((f[2] + f[3]) - (f[0] + f[1])))
    assert np.isclose(ty, h * ((f[1] + f[2]) - (f[0] + f[3])))
    assert np.isclose(tz, v.torque_to_thrust_m * ((f[1] + f[3]) - (f[0] + f[2])))


def test_usage_reaches_one_when_a_motor_saturates():
    v = SMALL_QUAD
    up = v.max_thrust_per_rotor_N - v.hover_thrust_per_rotor_N
    # a downward force taking all four motors to full thrust
    force = np.array([[0.0, 0.0, -4 * up]])
    assert np.isclose(authority_usage(v, force, np.zeros((1, 3)))[0], 1.0)
    # an upward force that idles every motor: the down headroom is the hover thrust
    force = np.array([[0.0, 0.0, v.weight_N]])
    assert np.isclose(authority_usage(v, force, np.zeros((1, 3)))[0], 1.0)
    # a roll torque uses the smaller of the two headrooms
    torque = np.array([[0.01, 0.0, 0.0]])
    f = motor_thrusts_N(v, np.zeros((1, 3)), torque)[0]
    assert f[0] > f[2]  # motors 1, 2 (-y) push harder to cancel a +x torque
    expected = max(np.abs(f - v.hover_thrust_per_rotor_N)) / min(up, v.hover_thrust_per_rotor_N)
    assert np.isclose(authority_usage(v, np.zeros((1, 3)), torque)[0], expected)
