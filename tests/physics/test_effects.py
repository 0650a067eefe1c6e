"""Tests of the shared effect library proxplan.physics.effects."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.physics import (
    BUILTIN_VEHICLES,
    EFFECT_NAMES,
    PARAMETERS,
    Effect,
    EffectInputs,
    ModelOptions,
    SourceSample,
    default_effect,
    disturbance_wrench,
    effect_wrench,
    total_wrench,
)

LARGE = BUILTIN_VEHICLES["large-quad"]
SMALL = BUILTIN_VEHICLES["small-quad"]


def _inputs(offsets, *, height=None, velocity=None, source=LARGE, target=SMALL):
    offsets = np.atleast_2d(np.asarray(offsets, dtype=float))
    n = offsets.shape[0]
    return EffectInputs(
        target=target,
        height_above_ground_m=np.full(n, 10.0) if height is None else np.asarray(height, float),
        velocity_mps=np.zeros((n, 3)) if velocity is None else np.asarray(velocity, float),
        sources=(SourceSample(source, offsets),),
    )


def test_parameters_cover_every_effect_with_ordered_bounds():
    assert set(PARAMETERS) == set(EFFECT_NAMES)
    for name, params in PARAMETERS.items():
        assert params, name
        for key, (default, lo, hi) in params.items():
            assert lo <= default <= hi, (name, key)
            assert lo < hi


@pytest.mark.parametrize("name", EFFECT_NAMES)
def test_every_effect_returns_finite_world_wrench_of_right_shape(name):
    offs = np.array([[0.0, 0.0, -1.5], [0.3, -0.2, -2.0], [0.1, 0.0, -0.8]])
    inputs = _inputs(offs, height=[0.1, 0.5, 3.0], velocity=[[0, 0, 1.0], [1, 0, 0], [0, 0, 0]])
    f, t = effect_wrench(default_effect(name), inputs)
    assert f.shape == (3, 3) and t.shape == (3, 3)
    assert np.all(np.isfinite(f)) and np.all(np.isfinite(t))


def test_effect_rejects_unknown_names_and_parameters():
    with pytest.raises(ValueError, match="unknown effect"):
        Effect("magic", {})
    with pytest.raises(ValueError, match="unknown parameter"):
        Effect("thrust_bias", {"force_N": 1.0})
    with pytest.raises(ValueError, match="finite"):
        Effect("thrust_bias", {"force_z_N": float("nan")})


def test_thrust_bias_is_constant_vertical_force():
    f, t = effect_wrench(Effect("thrust_bias", {"force_z_N": -0.3}), _inputs([[0, 0, -1], [1, 1, -2]]))
    np.testing.assert_allclose(f, [[0, 0, -0.3], [0, 0, -0.3]])
    np.testing.assert_allclose(t, 0.0)


def test_ground_effect_grows_near_ground_and_vanishes_far_away():
    h = np.array([0.1, 0.2, 0.5, 2.0, 50.0])
    inputs = _inputs(np.tile([0.0, 0.0, -2.0], (5, 1)), height=h)
    f, t = effect_wrench(Effect("ground_effect", {"gain_k": 1.0}), inputs)
    fz = f[:, 2]
    assert np.all(fz > 0.0)
    assert np.all(np.diff(fz) < 0.0)  # decreasing with height
    assert fz[-1] < 1e-4 * SMALL.weight_N
    # Cheeseman-Bennett ratio at one height, and doubling k roughly doubles the small excess
    r = SMALL.propeller.radius_m
    np.testing.assert_allclose(fz[3], SMALL.weight_N * (1 / (1 - (r / 8.0) ** 2) - 1), rtol=1e-9)
    f2, _ = effect_wrench(Effect("ground_effect", {"gain_k": 2.0}), inputs)
    assert 1.9 < f2[3, 2] / fz[3] < 2.1
    assert np.all(f2[:, 2] <= SMALL.weight_N * 1.0 + 1e-12)  # capped at ratio 2
    np.testing.assert_allclose(t, 0.0)


def test_near_field_scales_base_and_decays_with_depth():
    offs = np.array([[0.0, 0.0, -0.8], [0.0, 0.0, -1.6], [0.0, 0.0, -3.2], [0.0, 0.0, 0.5]])
    inputs = _inputs(offs)
    base = disturbance_wrench(LARGE, SMALL, offs)
    f, _ = effect_wrench(Effect("near_field", {"amplitude": 1.0, "decay_L": 2.0}), inputs)
    ratio = f[:3, 2] / base.force_N[:3, 2]
    np.testing.assert_allclose(ratio, np.exp(-offs[:3, 2] * -1 / (2.0 * LARGE.size_m)), rtol=1e-9)
    np.testing.assert_allclose(f[3], 0.0)  # target above the source
    f0, t0 = effect_wrench(Effect("near_field", {"amplitude": 0.0}), inputs)
    np.testing.assert_allclose(f0, 0.0)
    np.testing.assert_allclose(t0, 0.0)


def test_wake_swirl_gives_yaw_torque_proportional_to_base_force():
    offs = np.array([[0.0, 0.0, -1.5], [0.2, 0.1, -2.0]])
    base = disturbance_wrench(LARGE, SMALL, offs)
    f, t = effect_wrench(Effect("wake_swirl", {"yaw_per_force_m": 0.05}), _inputs(offs))
    np.testing.assert_allclose(f, 0.0)
    np.testing.assert_allclose(t[:, :2], 0.0)
    np.testing.assert_allclose(t[:, 2], 0.05 * base.force_N[:, 2])
    assert np.all(t[:, 2] < 0.0)


def test_wake_advection_moves_the_wake_downstream():
    dz, wind, conv = 2.0, 1.0, 2.0
    shift = wind * dz / conv
    effect = Effect("wake_advection", {"wind_x_mps": wind, "convection_speed_mps": conv})
    # a target sitting where the advected wake axis is feels the on-axis base wrench
    offs = np.array([[shift, 0.0, -dz]])
    f, _ = effect_wrench(effect, _inputs(offs))
    on_axis = disturbance_wrench(LARGE, SMALL, np.array([[0.0, 0.0, -dz]]))
    here = disturbance_wrench(LARGE, SMALL, offs)
    np.testing.assert_allclose(here.force_N + f, on_axis.force_N, rtol=1e-9, atol=1e-12)
    assert abs(f[0, 2]) > 0.01 * abs(on_axis.force_N[0, 2])
    # no wind, no effect
    f0, t0 = effect_wrench(Effect("wake_advection", {}), _inputs(offs))
    np.testing.assert_allclose(f0, 0.0)
    np.testing.assert_allclose(t0, 0.0)


def test_own_velocity_sign_conventions():
    vel = np.array([[0, 0, 0.0], [0, 0, 1.0], [2.0, 0, 0]])
    eff = Effect("own_velocity", {"c_w_spm": 0.1, "c_mu_spm": 0.0, "c_mu2_s2pm2": 0.02})
    f, _ = effect_wrench(eff, _inputs(np.tile([0, 0, -2.0], (3, 1)), velocity=vel))
    assert f[0, 2] == 0.0
    np.testing.assert_allclose(f[1, 2], -0.1 * SMALL.weight_N)  # climbing loses thrust
    np.testing.assert_allclose(f[2, 2], 0.02 * 4.0 * SMALL.weight_N)


def test_thrust_quadratic_is_a_loss_growing_faster_than_linear_model():
    offs = np.array([[0.0, 0.0, -1.0], [0.0, 0.0, -2.0]])
    eff = Effect("thrust_quadratic", {"b_q_rel_spm": 0.2})
    f, t = effect_wrench(eff, _inputs(offs))
    assert np.all(f[:, 2] < 0.0)
    base = disturbance_wrench(LARGE, SMALL, offs)
    # quadratic in v_on: the ratio to the linear thrust change grows as the wake gets faster
    r = f[:, 2] / base.thrust_force_N[:, 2]
    assert r[0] > r[1] > 0.0
    f2, _ = effect_wrench(Effect("thrust_quadratic", {"b_q_rel_spm": 0.4}), _inputs(offs))
    np.testing.assert_allclose(f2, 2 * f)
    # off-axis target gets a roll torque
    _, t_off = effect_wrench(eff, _inputs([[0.0, 0.15, -1.0]]))
    assert abs(t_off[0, 0]) > 1e-6


def test_total_wrench_is_base_plus_effects_summed_over_sources():
    offs_a = np.array([[0.0, 0.0, -1.5], [0.1, 0.0, -1.0]])
    offs_b = np.array([[0.1, 0.2, -2.0], [0.0, 0.0, -3.0]])
    inputs = EffectInputs(
        target=SMALL,
        height_above_ground_m=np.array([0.3, 1.0]),
        velocity_mps=np.zeros((2, 3)),
        sources=(SourceSample(LARGE, offs_a), SourceSample(SMALL, offs_b)),
        options=ModelOptions(stack_shielding=0.0),  # S0's superposition; shielding: tests/physics/test_stack.py
    )
    effects = [Effect("thrust_bias", {"force_z_N": 0.1}), default_effect("ground_effect")]
    f, t = total_wrench(inputs, effects)
    base_a = disturbance_wrench(LARGE, SMALL, offs_a)
    base_b = disturbance_wrench(SMALL, SMALL, offs_b)
    extra = [effect_wrench(e, inputs) for e in effects]
    np.testing.assert_allclose(f, base_a.force_N + base_b.force_N + sum(x[0] for x in extra))
    np.testing.assert_allclose(t, base_a.torque_Nm + base_b.torque_Nm + sum(x[1] for x in extra))
    # no sources, no effects: nothing
    lone = EffectInputs(SMALL, np.array([1.0]), np.zeros((1, 3)), ())
    f0, t0 = total_wrench(lone)
    np.testing.assert_allclose(f0, 0.0)
    np.testing.assert_allclose(t0, 0.0)


@pytest.mark.parametrize("name", EFFECT_NAMES)
def test_strength_parameters_at_zero_switch_the_effect_off(name):
    """Issue 29's identification test reads EFFECT_STRENGTHS: their zero must leave nothing."""
    from proxplan.physics import EFFECT_STRENGTHS

    assert set(EFFECT_STRENGTHS) == set(EFFECT_NAMES)
    offs = np.array([[0.0, 0.0, -1.5], [0.3, -0.2, -2.0], [0.1, 0.0, -0.8]])
    inputs = _inputs(offs, height=[0.1, 0.5, 3.0], velocity=[[0, 0, 1.0], [1, 0, 0], [0, 0, -0.5]])
    zeroable = [k for k in EFFECT_STRENGTHS[name] if PARAMETERS[name][k][1] <= 0.0]  # decays switch off at 0-
    assert zeroable, name
    params = default_effect(name).full_params() | {k: 0.0 for k in zeroable}
    f, t = effect_wrench(Effect(name, params), inputs)
    np.testing.assert_allclose(f, 0.0, atol=1e-15)
    np.testing.assert_allclose(t, 0.0, atol=1e-15)


def test_climb_inflow_is_s0_6_with_the_target_climb_speed():
    """Delta F_z = -g (b_v / k1) v_z T: a falling vehicle gains thrust, a climbing one loses it, in
    proportion to its own thrust (the weight when the thrust is unknown)."""
    inputs = _inputs(np.tile([0.0, 0.0, -2.0], (3, 1)), velocity=[[0, 0, -1.0], [0, 0, 0.0], [0, 0, 0.5]])
    f, t = effect_wrench(Effect("climb_inflow", {"gain_1": 1.0}), inputs)
    per_mps = SMALL.b_v / SMALL.propeller.k1_Ns2prad2 * SMALL.weight_N
    np.testing.assert_allclose(f[:, 2], [per_mps, 0.0, -0.5 * per_mps], rtol=1e-12)
    np.testing.assert_allclose(t, 0.0)
    from dataclasses import replace

    doubled = replace(inputs, thrust_z_N=np.full(3, 2.0 * SMALL.weight_N))
    np.testing.assert_allclose(effect_wrench(Effect("climb_inflow", {"gain_1": 1.0}), doubled)[0], 2.0 * f)


def test_floor_stagnation_stops_the_jet_at_the_floor_and_not_far_above():
    offs = np.tile([0.0, 0.0, -0.6], (3, 1))
    inputs = _inputs(offs, height=[0.0, 0.15, 20.0])
    base = total_wrench(inputs, ())[0][:, 2]
    f, _ = effect_wrench(Effect("floor_stagnation", {"amplitude_1": 1.0, "decay_widths": 1.0}), inputs)
    np.testing.assert_allclose(f[0, 2], -base[0], rtol=1e-9)  # the whole push cancelled at the floor
    assert 0.0 < f[1, 2] / -base[1] < 1.0  # partly in between
    assert abs(f[2, 2]) < 1e-9 * abs(base[2])  # nothing far above the floor


def test_a_delayed_effect_is_its_wrench_on_the_inputs_of_that_much_earlier():
    """LAG_PARAM (issue 35): along a clock the delayed effect is the undelayed one shifted by lag_s (held at
    the start); without a clock (a steady state) the delay changes nothing."""
    t = np.arange(0.0, 4.0, 0.01)
    offsets = np.column_stack([0.3 * np.sin(2.0 * t), 0.1 * np.cos(3.0 * t), -0.4 + 0.1 * np.sin(t)])
    inputs = EffectInputs(target=SMALL, height_above_ground_m=np.full(len(t), 2.0), velocity_mps=np.zeros((len(t), 3)),
                          sources=(SourceSample(LARGE, offsets),), time_s=t)  # fmt: skip
    at_once = effect_wrench(Effect("near_field", {"amplitude": 1.0}), inputs)
    late = effect_wrench(Effect("near_field", {"amplitude": 1.0, "lag_s": 0.25}), inputs)
    for now, then in zip(at_once, late):
        np.testing.assert_allclose(then[25:], now[:-25], atol=1e-15)
        np.testing.assert_allclose(then[:25], np.repeat(now[:1], 25, axis=0), atol=1e-15)
    assert np.abs(late[0] - at_once[0]).max() > 0.1 * np.abs(at_once[0]).max()  # the delay matters here
    steady = EffectInputs(target=SMALL, height_above_ground_m=np.full(3, 2.0), velocity_mps=np.zeros((3, 3)),
                          sources=(SourceSample(LARGE, offsets[:3]),))  # fmt: skip
    np.testing.assert_array_equal(effect_wrench(Effect("near_field", {"lag_s": 0.25}), steady)[0],
                                  effect_wrench(Effect("near_field", {}), steady)[0])  # fmt: skip
    with pytest.raises(ValueError, match="lag_s"):
        Effect("near_field", {"lag_s": -0.1})


def test_wake_memory_is_a_share_of_the_base_downwash():
    inputs = _inputs([[0.05, 0.0, -0.5], [0.2, 0.1, -0.8], [0.0, 0.0, 0.4]])
    f0, t0 = total_wrench(inputs, ())
    f, t = effect_wrench(Effect("wake_memory", {"share_1": 0.4}), inputs)
    np.testing.assert_allclose(f, 0.4 * f0, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(t, 0.4 * t0, rtol=1e-12, atol=1e-15)
    assert abs(f0[0, 2]) > 0.0  # a source above pushes
