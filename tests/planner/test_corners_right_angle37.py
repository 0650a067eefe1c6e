"""Round 37U (issue 37): a right-angled corner of a run through waypoints is flown through rest on every
machine. A lane route's offset legs are perpendicular to its middle leg by construction, so their cosine is 0
exactly and comes out as +-1e-17 by the last bits of the legs, which differ from machine to machine (numpy's
SIMD kernels: pillar-256 by type, the Crazyflie level's vehicle 7, rounded with AVX2 keep-outs, at rest with
AVX-512 ones, 227 against 230 grid steps). The turn is now compared after rounding (``TURN_COS_RESOLUTION``)."""

from __future__ import annotations

import numpy as np

from proxplan.physics import KinematicLimits
from proxplan.planner.timing.corners import MAX_TURN_COS, corner_speeds, passes_moving, through_run
from proxplan.planner.timing.profile import RunMove

LIMITS = KinematicLimits(max_speed_mps=2.0, max_accel_mps2=4.0, max_jerk_mps3=16.0)  # the Crazyflie's
DT_S = 0.025  # the swarm layer's grid step, s

# pillar-256 by type, Crazyflie level, vehicle 7: its start, start + D, goal + D (m), with the keep-outs built
# under numpy's AVX-512 kernels (cosine of the first corner -2.1e-17) and its AVX2 ones (+5.6e-17)
AVX512_M = np.array(
    [
        [-0.8, -0.3, 1.8296668945312495],
        [-0.7908930264435188, -0.5398169703206737, 2.3296668945312495],
        [7.109106973556481, -0.23981697032067362, 2.3296668945312495],
    ]
)
AVX2_M = np.array(
    [
        [-0.8, -0.3, 1.8296668945312495],
        [-0.7908930264435189, -0.5398169703206696, 2.3296668945312495],
        [7.1091069735564805, -0.23981697032066954, 2.3296668945312495],
    ]
)


def _cos_first_corner(pts: np.ndarray) -> float:
    d = np.diff(pts, axis=0)
    u = d / np.linalg.norm(d, axis=1, keepdims=True)
    return float(np.dot(u[0], u[1]))


def test_the_recorded_routes_straddle_the_right_angle():
    # the two sides of the last bit, as the two machines' kernels leave them
    assert _cos_first_corner(AVX512_M) <= MAX_TURN_COS < _cos_first_corner(AVX2_M)


def test_a_right_angle_within_the_last_bits_is_flown_through_rest_on_both():
    for pts in (AVX512_M, AVX2_M):
        assert corner_speeds(pts, LIMITS).tolist() == [0.0, 0.0, 0.0]
    steps = [RunMove(pts, LIMITS, DT_S, deviation_m=0.15).steps for pts in (AVX512_M, AVX2_M)]
    assert steps[0] == steps[1], steps
    dur = [[float(p.duration) for p in through_run(pts, LIMITS)] for pts in (AVX512_M, AVX2_M)]
    assert len(dur[0]) == len(dur[1]) == 2  # two straight legs, through rest at the corner
    assert np.allclose(dur[0], dur[1], rtol=0.0, atol=1e-9)


def test_one_ulp_either_side_of_the_right_angle_decides_the_same():
    zero = 0.0
    for c in (zero, np.nextafter(zero, 1.0), np.nextafter(zero, -1.0), 1e-16, -1e-16, 5.6e-17, -2.1e-17):
        assert not passes_moving(float(c)), c


def test_a_turn_under_90_degrees_is_still_rounded():
    # 89.99 degrees (cos 1.7e-4) and 45 degrees are passed moving: the rounding changes only the last bits
    assert passes_moving(float(np.cos(np.radians(89.99))))
    assert passes_moving(float(np.cos(np.radians(45.0))))
    assert not passes_moving(float(np.cos(np.radians(90.01))))
    pts = np.array([[0.0, 0.0, 1.0], [2.0, 0.0, 1.0], [4.0, 2.0, 1.0]])  # a 45-degree corner
    assert corner_speeds(pts, LIMITS)[1] > 0.0
