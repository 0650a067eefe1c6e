"""The tracking error of a vehicle along its own reference (proxplan.physics.tracking_loop): the
discretisation, the set-point frame's yaw rate, and what the loop does on references whose answer
is known."""

from __future__ import annotations

import dataclasses

import numpy as np
from scipy.signal import cont2discrete

from proxplan.physics import (
    BUILTIN_VEHICLES,
    GRAVITY_MPS2,
    SETPOINT_DELAY_S,
    ReferenceSamples,
    RotorDrag,
    tracking_response,
)
from proxplan.physics.discretize import foh_maps
from proxplan.physics.tracking_loop import frame_yaw_rate_radps


def test_first_order_hold_is_scipys():
    rng = np.random.default_rng(0)
    a = rng.normal(size=(5, 5)) - 2.0 * np.eye(5)
    b = rng.normal(size=(5, 2))
    phi, g0, g1 = foh_maps(a, b, 0.05)
    ad, bd, _, dd, _ = cont2discrete((a, b, np.eye(5), np.zeros((5, 2))), 0.05, method="foh")
    # scipy's states are shifted by Gamma_1 u: x = xi + Gamma_1 u
    assert np.allclose(ad, phi, atol=1e-12)
    assert np.allclose(bd, g0 - g1 + phi @ g1, atol=1e-12)
    assert np.allclose(dd, g1, atol=1e-12)


def _frame(acc: np.ndarray) -> np.ndarray:
    z = acc + np.array([0.0, 0.0, GRAVITY_MPS2])
    z /= np.linalg.norm(z, axis=1, keepdims=True)
    y = np.cross(z, [1.0, 0.0, 0.0])
    y /= np.linalg.norm(y, axis=1, keepdims=True)
    return np.stack([np.cross(y, z), y, z], axis=2)  # columns x, y, z


def test_the_set_point_frame_turns_about_its_z_axis():
    """Zero for accelerations along x or y (the frame tilts about a fixed axis); the frame's own
    rate (R^T R' = [w]x, differentiated numerically) on a circle's and a diagonal line's."""
    t = np.linspace(0.0, 2.0, 4001)
    for axis in ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]):
        line = np.outer(3.0 * np.sin(3.0 * t), axis)
        assert np.allclose(frame_yaw_rate_radps(line, np.gradient(line, t, axis=0)), 0.0, atol=1e-12)
    circle = 3.6 * np.column_stack([np.cos(3.5 * t), np.sin(3.5 * t), np.zeros(t.size)])
    diagonal = np.outer(3.0 * np.sin(3.0 * t), [0.6, 0.8, 0.0])
    for acc in (circle, diagonal):
        r = _frame(acc)
        w = np.einsum("kji,kjl->kil", r, np.gradient(r, t, axis=0))  # R^T R' = [w]x
        got = frame_yaw_rate_radps(acc, np.gradient(acc, t, axis=0))
        assert np.allclose(got[5:-5], w[5:-5, 1, 0], atol=1e-4)
        assert np.abs(got).max() > 0.03  # (0.064 rad/s on the line, 0.9 on the circle)


def test_a_cruise_lags_its_plan_by_the_set_point_hold():
    """No drag, a reference half a set-point period late: at a steady cruise the vehicle flies the
    reference exactly (the loop's steady state), so it is v x delay behind its plan."""
    vehicle = dataclasses.replace(BUILTIN_VEHICLES["crazyflie-2.1"], rotor_drag=RotorDrag(0.0, 0.0))
    t = np.arange(0.0, 30.0 + 1e-9, 0.01)
    speed = np.clip(t / 2.0, 0.0, 1.0) * 1.5  # ramp to 1.5 m/s in 2 s, then cruise
    pos = np.where(t < 2.0, 0.375 * t**2, 1.5 + 1.5 * (t - 2.0))  # its integral, m
    zero = np.zeros((t.size, 3))

    def xyz(x):
        out = zero.copy()
        out[:, 0] = x
        return out

    acc = np.gradient(speed, t)
    late = t - SETPOINT_DELAY_S
    samples = ReferenceSamples(
        t, xyz(pos), xyz(speed), xyz(acc), xyz(np.interp(late, t, pos)), xyz(np.interp(late, t, speed)),
        xyz(np.interp(late, t, acc)), zero, zero,
    )  # fmt: skip
    err = tracking_response(vehicle, samples).error_m
    assert np.allclose(err[-1], [-1.5 * SETPOINT_DELAY_S, 0.0, 0.0], atol=1e-4), err[-1]


def test_the_heading_first_then_one_recursion_is_stepping_the_twist():
    """On a curve (the set-point frame turns, so the heading twists the roll / pitch feed-forward)
    the run with the heading's subsystem solved first and the twist as a known drive gives what
    stepping the twist sample by sample gives (the verifier's loop before round 13C), to rounding;
    and the heading's subsystem is closed for every built-in vehicle."""
    from proxplan.physics.tracking_loop import _heading_states, _maps, _run, reference_drive

    t = np.arange(0.0, 6.0 + 1e-9, 0.01)
    w = 2.0
    p = 0.8 * np.column_stack([np.cos(w * t), np.sin(w * t), 0.1 * t])
    v = 0.8 * w * np.column_stack([-np.sin(w * t), np.cos(w * t), np.full(t.size, 0.1 / w)])
    a = -(w**2) * 0.8 * np.column_stack([np.cos(w * t), np.sin(w * t), np.zeros(t.size)])
    j = 0.8 * w**3 * np.column_stack([np.sin(w * t), -np.cos(w * t), np.zeros(t.size)])
    ref = ReferenceSamples(t, p, v, a, p + 0.01, v, a, j, -(w**2) * a)  # snap of the circle: -w^2 a
    for name, vehicle in sorted(BUILTIN_VEHICLES.items()):
        m = _maps(vehicle, 0.01)
        yaw = int(np.searchsorted(m.live, 8))
        assert _heading_states(m, yaw) is not None, name
        s = reference_drive(vehicle, ref)
        assert np.abs(s[:, 21]).max() > 0.1  # the frame turns
        forced = np.einsum("ki,ji->kj", s[:-1], m.g0 - m.g1) + np.einsum("ki,ji->kj", s[1:], m.g1)
        x0 = np.linspace(-1e-3, 1e-3, m.live.size)
        want = np.zeros((t.size, m.live.size))
        want[0] = x = x0
        for i in range(t.size - 1):
            x = m.phi @ x + forced[i] + m.g_att @ (x[yaw] * np.array([-s[i, 10], s[i, 9]]))
            want[i + 1] = x
        got = _run(m, s, x0, twist=True)
        assert np.allclose(got, want, rtol=0.0, atol=1e-12 * np.abs(want).max()), name
