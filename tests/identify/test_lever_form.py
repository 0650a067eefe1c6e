"""A side-axis torque term's lever form (:mod:`proxplan.identify.lever_form`): a neighbour's force c W k acting at
the lever arm y (m) off the target's centre is the torque c W k y whatever the two vehicles' sizes, which the
side axis (y over the NEIGHBOUR's size, the term scaled by the target's W L) describes only with a coefficient per
pair of sizes. With three vehicle types a target under two neighbours of different sizes needs two coefficients for
one type, which neither one coefficient nor one per target type gives (bench block 34000, draws 6 and 11)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from proxplan.identify.data import IdentifyOptions
from proxplan.identify.lever_form import lever_key
from proxplan.physics import (
    BUILTIN_VEHICLES,
    DISCOVERED_PREFIX,
    Effect,
    EffectInputs,
    SourceSample,
    effect_wrench,
    feature_matrix,
    is_feature,
    parse_basis_name,
)
from tests.identify.synthetic_runs import identify_flights, kept_terms, torque_rmse_on_test_Nm

KERNEL = "above_g1L_e4L_1"
"""The hidden torque's kernel: exp(-(r / L)^2 - dz / 4 L) of the neighbours above (L the neighbour's size), a
kernel of the declared grid (the form is what is judged here, not the search for a shape)."""
LEVER_C = 0.05
"""The hidden roll torque per unit of the target's weight times the kernel times the lever arm y (-)."""
TYPES = {"a": "large-quad", "b": "small-quad", "c": "crazyflie-parrot"}
OPTIONS = IdentifyOptions(max_fit_samples=4000, max_eval_samples=3000)


def test_the_lever_form_is_the_force_at_its_lever_arm() -> None:
    """``..._y_1`` -> ``..._yt_1`` on weight-scaled untyped torque terms only; applied, c W k y on any target under
    any neighbour (the side axis gives c W L_t k y / L instead)."""
    key = "torque_x_Nm*W*above_g1L_e4L_y_1"
    assert lever_key(key) == "torque_x_Nm*W*above_g1L_e4L_yt_1"
    assert lever_key("torque_y_Nm*W*side_c0p4L_e1L_x_1") == "torque_y_Nm*W*side_c0p4L_e1L_xt_1"
    for other in ("force_z_N*W*above_g1L_e4L_y_1", "torque_x_Nm*W*above_g1L_e4L_1", key + "@small-quad",
                  "torque_x_Nm*W*above_g1L_e4L_rel_speed_xy_mps"):  # fmt: skip
        assert lever_key(other) is None, other
    lever = "above_g1L_e4L_yt_1"
    assert is_feature(lever) and parse_basis_name(lever)[1] == "yt"
    n = 7
    offsets = np.column_stack([0.05 * np.ones(n), np.linspace(-0.3, 0.3, n), -0.45 * np.ones(n)])  # 0.45 m below it
    r, dz = np.hypot(offsets[:, 0], offsets[:, 1]), -offsets[:, 2]
    for target in TYPES.values():
        for source in TYPES.values():
            veh, src = BUILTIN_VEHICLES[target], BUILTIN_VEHICLES[source]
            inputs = EffectInputs(
                veh, np.full(n, 1.0), np.zeros((n, 3)), (SourceSample(src, offsets, np.zeros((n, 3))),)
            )
            k = np.exp(-((r / src.size_m) ** 2) - dz / (4.0 * src.size_m))
            tau = effect_wrench(Effect(DISCOVERED_PREFIX + "t", {lever_key(key): LEVER_C}), inputs)[1][:, 0]
            np.testing.assert_allclose(tau, LEVER_C * veh.weight_N * k * offsets[:, 1], rtol=1e-12, atol=1e-15)
            side = effect_wrench(Effect(DISCOVERED_PREFIX + "t", {key: LEVER_C}), inputs)[1][:, 0]
            np.testing.assert_allclose(side, tau * veh.size_m / src.size_m, rtol=1e-12, atol=1e-15)


def _roll_at_lever_arm(inputs: EffectInputs) -> tuple[np.ndarray, np.ndarray]:
    """tau_x = C W_target sum over the neighbours above of k y, y the lever arm (m): per unit of the side axis'
    W_t L_t k y / L it is C L / L_t, a different coefficient under each neighbour's size."""
    force, torque = np.zeros((inputs.n_samples, 3)), np.zeros((inputs.n_samples, 3))
    zero = [(np.zeros((inputs.n_samples, 3)), np.zeros((inputs.n_samples, 3))) for _ in inputs.sources]
    for src, z in zip(inputs.sources, zero):
        one = replace(inputs, sources=(src,))
        k = feature_matrix(one, [z], [KERNEL])[:, 0]
        torque[:, 0] += LEVER_C * inputs.target.weight_N * k * np.asarray(src.offsets_m)[:, 1]
    return force, torque


def _stack(t: np.ndarray, phase: float, large_on_top: bool) -> dict[str, np.ndarray]:
    """Three layers, the Parrot 'c' always lowest (0.8 m), the large 'a' and the small 'b' quads above it taking
    turns on top (1.3 m and 1.9 m); each sways across its roll axis (y) so the others pass over it."""

    def path(ax: float, ay: float, fx: float, fy: float, z: float, p: float) -> np.ndarray:
        return np.column_stack([ax * np.sin(2 * np.pi * t / fx + p), ay * np.sin(2 * np.pi * t / fy + 2 * p),
                                z + 0.03 * np.sin(2 * np.pi * t / 5.0 + p)])  # fmt: skip

    top, mid = (1.9, 1.3) if large_on_top else (1.3, 1.9)
    return {"a": path(0.08, 0.25, 5.0, 3.3, top, phase), "b": path(0.06, 0.22, 6.0, 2.9, mid, phase + 1.1),
            "c": path(0.07, 0.28, 4.4, 3.7, 0.8, phase + 2.3)}  # fmt: skip


def _run(tmp: Path, hidden):
    return identify_flights(tmp, TYPES, lambda t, k: _stack(t, 0.9 * k, k % 2 == 0), hidden, options=OPTIONS,
                            n_flights=7, n_test=2)  # fmt: skip


@pytest.mark.slow
def test_a_torque_at_its_lever_arm_is_kept_in_the_lever_form(tmp_path: Path) -> None:
    """Three types, the Parrot under the small and the large quad: the hidden roll is the lever form of a grid
    kernel. The lever form is kept with one coefficient near C, and every vehicle's test torque is within 1.3x of
    its clean twin's (which keeps nothing); without the lever form the best the grid offers is one coefficient per
    target type, which cannot serve the Parrot's two neighbours."""
    clean = _run(tmp_path / "clean", None)
    result = _run(tmp_path / "effect", _roll_at_lever_arm)
    assert not [e for e in clean.discovered if e["selected"]]
    kept = kept_terms(result)
    lever = {k: v for k, v in kept.items() if k.startswith("torque_x_Nm*W*above_") and "_yt_1" in k}
    assert len(lever) == 1 and not any("@" in k for k in kept), kept
    assert abs(next(iter(lever.values())) / LEVER_C - 1.0) < 0.3, kept

    for vehicle in TYPES:
        assert torque_rmse_on_test_Nm(result, vehicle) <= 1.3 * torque_rmse_on_test_Nm(clean, vehicle), (vehicle, kept)
