"""Feature dictionary (proxplan.physics.features) and discovered terms as effects (proxplan.physics.effects)."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.physics import (
    BUILTIN_VEHICLES,
    FEATURE_NAMES,
    Effect,
    EffectInputs,
    SourceSample,
    base_wrench,
    disturbance_wrench,
    effect_wrench,
    feature_matrix,
    total_wrench,
)
from proxplan.physics.time_copies import lagged, lowpass

VEH = BUILTIN_VEHICLES["small-quad"]


def _inputs(offsets: np.ndarray, *, t: np.ndarray | None = None, h: float = 1.0, src_vel=None) -> EffectInputs:
    n = len(offsets)
    return EffectInputs(
        target=VEH,
        height_above_ground_m=np.full(n, h),
        velocity_mps=np.zeros((n, 3)),
        sources=(SourceSample(VEH, offsets, src_vel),),
        time_s=t,
    )


def _features(inputs: EffectInputs) -> dict[str, np.ndarray]:
    per = [
        (b.force_N, b.torque_Nm)
        for b in (disturbance_wrench(s.vehicle, inputs.target, s.offsets_m, inputs.options) for s in inputs.sources)
    ]
    x = feature_matrix(inputs, per)
    assert x.shape == (inputs.n_samples, len(FEATURE_NAMES))
    return dict(zip(FEATURE_NAMES, x.T))


def test_every_feature_names_its_unit() -> None:
    assert all(
        n.rsplit("_", 1)[-1] in {"1", "m", "mps", "m2ps2", "N", "Nm", "Nmps", "1pm", "m2"} for n in FEATURE_NAMES
    )


def test_pairwise_features_vanish_far_from_sources_and_separate_above_below() -> None:
    offsets = np.array([[0.0, 0.0, -0.4], [0.0, 0.0, 0.4], [5.0, 0.0, -0.4], [0.3, 0.0, 0.0]])
    f = _features(_inputs(offsets))
    assert f["above_jet_1"][0] > 0.1 and f["above_jet_1"][1] == 0.0  # source above vs below
    assert f["below_near_1"][1] > 0.01 and f["below_near_1"][0] == 0.0
    assert f["side_near_1"][3] > f["side_near_1"][0]
    pairwise = [n for n in FEATURE_NAMES if n.startswith(("above_", "below_", "side_", "base_"))]
    assert all(abs(f[n][2]) < 1e-6 for n in pairwise)  # 5 m away horizontally
    assert f["base_fz_N"][0] < 0.0  # downwash pushes down (S0-7)


def test_relative_speed_from_source_velocity_or_clock() -> None:
    t = np.arange(0.0, 1.0, 0.01)
    offsets = np.column_stack([0.2 * t - 0.1, 0 * t, -0.4 + 0 * t])  # source slides by at 0.2 m/s
    by_clock = _features(_inputs(offsets, t=t))
    by_velocity = _features(_inputs(offsets, src_vel=np.tile([-0.2, 0.0, 0.0], (len(t), 1))))
    ratio = by_clock["above_jet_rel_speed_xy_mps"] / by_clock["above_jet_1"]
    assert np.allclose(ratio, 0.2, rtol=1e-6)
    assert np.allclose(by_clock["above_jet_rel_speed_xy_mps"], by_velocity["above_jet_rel_speed_xy_mps"])
    static = _features(_inputs(offsets))  # no clock, no source velocity: at rest
    assert np.all(static["above_jet_rel_speed_xy_mps"] == 0.0)


def test_lag_and_lowpass_follow_the_clock_and_restart_on_gaps() -> None:
    t = np.concatenate([np.arange(0.0, 1.0, 0.01), 5.0 + np.arange(0.0, 1.0, 0.01)])
    x = np.where((t > 0.5) & (t < 5.0), 1.0, 0.0)
    lag = lagged(x, t, 0.1)
    assert lag[np.searchsorted(t, 0.55)] == 0.0 and lag[np.searchsorted(t, 0.65)] == 1.0
    lp = lowpass(x, t, 0.3)
    k = np.searchsorted(t, 0.8)
    assert lp[k] == pytest.approx(1.0 - np.exp(-(t[k] - 0.51) / 0.3), abs=0.03)
    assert lp[100] == 0.0  # new run after the gap starts from its own first value
    assert np.array_equal(lowpass(x, None), x) and np.array_equal(lagged(x, None), x)


def test_discovered_term_is_name_params_and_acts_between_vehicles() -> None:
    eff = Effect("discovered:force_z_N", {"force_z_N*above_jet_1": -0.05, "torque_x_Nm*ground_cb_1": 0.01})
    assert eff.features == ("above_jet_1", "ground_cb_1")
    assert Effect(eff.name, eff.full_params()) == eff
    near = _inputs(np.array([[0.0, 0.0, -0.4]]), h=0.05)
    far = _inputs(np.array([[4.0, 0.0, -0.4]]), h=2.0)
    f_near, t_near = effect_wrench(eff, near)
    f_far, _ = effect_wrench(eff, far)
    assert f_near[0, 2] < -0.01 and abs(f_far[0, 2]) < 1e-9
    assert t_near[0, 0] > 0.0 and np.all(f_near[:, :2] == 0.0)
    total, _ = total_wrench(near, (eff,))
    assert total[0, 2] == pytest.approx(base_wrench(near)[0][0, 2] + f_near[0, 2])


@pytest.mark.parametrize("key", ["force_z_N*no_such_feature", "force_w_N*one_1", "one_1"])
def test_unknown_term_parameter_is_rejected(key: str) -> None:
    with pytest.raises(ValueError, match="discovered-term parameter"):
        Effect("discovered:x", {key: 1.0})


def test_discovered_term_round_trips_the_model_file_list_and_acts_between_vehicles_only_pairwise() -> None:
    from proxplan.fileio import UserError
    from proxplan.physics import between_vehicle_effects, effects_from_list, effects_to_list

    eff = Effect("discovered:force_z_N", {"force_z_N*one_1": 0.01, "force_z_N*above_core_rel_speed_xy_mps": -0.6})
    (back,) = effects_from_list(effects_to_list([eff]), "m.yaml: model.effects")
    assert back == eff
    (pair,) = between_vehicle_effects([eff])
    assert pair.params == {"force_z_N*above_core_rel_speed_xy_mps": -0.6}
    assert between_vehicle_effects([Effect("discovered:x", {"force_z_N*one_1": 0.01})]) == ()
    with pytest.raises(UserError, match=r"m.yaml: model.effects\[0\].params: discovered-term parameter"):
        effects_from_list([{"name": "discovered:x", "params": {"force_z_N*nope": 1.0}}], "m.yaml: model.effects")


def test_cost_maps_apply_the_pairwise_part_of_a_discovered_term() -> None:
    from proxplan.costmaps import pair_wrench

    eff = Effect("discovered:residual", {"force_z_N*one_1": 0.5, "force_z_N*above_core_1": -0.04})
    offsets = np.array([[0.0, 0.0, -0.3], [3.0, 0.0, -0.3]])
    f0, _ = pair_wrench(VEH, VEH, offsets)
    f1, _ = pair_wrench(VEH, VEH, offsets, effects=(eff,))
    core = np.exp(0.0) / (1.0 + 0.3 / (3.0 * VEH.size_m))
    assert f1[0, 2] - f0[0, 2] == pytest.approx(-0.04 * core, rel=1e-9)  # the constant is not a pair effect
    assert f1[1, 2] - f0[1, 2] == pytest.approx(0.0, abs=1e-12)


def test_side_kernels_bracket_a_profile_in_the_height_difference() -> None:
    """A neighbour level with the target (offset only in z): the Gaussian and the Laplace side profiles agree at
    dz = 0 and the Laplace one keeps more at a larger height difference (a term fitted at one flight's gap carries
    to another's by its tail); above and below keep one Gaussian profile (no Laplace features there)."""
    L = VEH.size_m
    dz = np.array([0.0, 1.0, 3.0]) * L
    f = _features(_inputs(np.column_stack([np.zeros(3), np.zeros(3), dz])))
    g, lap = f["side_g1L_e4L_1"], f["side_l1L_e4L_1"]
    assert g[0] == pytest.approx(1.0) and lap[0] == pytest.approx(1.0)
    assert lap[1] == pytest.approx(np.exp(-1.0)) and g[1] == pytest.approx(np.exp(-1.0))
    assert lap[2] == pytest.approx(np.exp(-3.0)) and g[2] == pytest.approx(np.exp(-9.0))
    assert not any(n.startswith(("above_l", "below_l")) for n in FEATURE_NAMES)
