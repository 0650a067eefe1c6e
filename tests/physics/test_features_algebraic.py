"""The algebraic forms of the multi-scale kernels and of the ground proximity (stop 64): the shapes the names declare."""

from __future__ import annotations

import numpy as np

from proxplan.physics import BUILTIN_VEHICLES, FEATURE_NAMES, EffectInputs, SourceSample, feature_matrix
from proxplan.physics.features import feature_group, ground_names

VEH = BUILTIN_VEHICLES["small-quad"]
L = VEH.size_m


def _f(offsets: np.ndarray, h_m: float = 1.0) -> dict[str, np.ndarray]:
    n = len(offsets)
    inputs = EffectInputs(target=VEH, height_above_ground_m=np.full(n, h_m), velocity_mps=np.zeros((n, 3)),
                          sources=(SourceSample(VEH, offsets, np.zeros((n, 3))),))  # fmt: skip
    zeros = [(np.zeros((n, 3)), np.zeros((n, 3)))]
    return dict(zip(FEATURE_NAMES, feature_matrix(inputs, zeros).T))


def test_the_algebraic_decay_keeps_a_heavy_tail_where_the_exponential_does_not() -> None:
    """A neighbour straight above at 1 and 10 decay lengths (4 L): 1 / (1 + x) falls 5.5x, exp(-x) 8100x; below the
    same with the neighbour under the target; each is zero on the other side."""
    depths = np.array([4.0 * L, 40.0 * L])
    above = _f(np.column_stack([0 * depths, 0 * depths, -depths]))  # offsets = p_target - p_source: source above
    below = _f(np.column_stack([0 * depths, 0 * depths, depths]))
    for f, where, other in ((above, "above", below), (below, "below", above)):
        inv, exp = f[f"{where}_g1L_i4L_1"], f[f"{where}_g1L_e4L_1"]
        np.testing.assert_allclose(inv, 1.0 / (1.0 + depths / (4.0 * L)), rtol=1e-12)
        np.testing.assert_allclose(exp, np.exp(-depths / (4.0 * L)), rtol=1e-12)
        assert inv[0] / inv[1] < 6.0 and exp[0] / exp[1] > 8000.0
        assert np.all(other[f"{where}_g1L_i4L_1"] == 0.0)


def test_the_cauchy_profile_beside_is_lorentzian_in_the_height_difference() -> None:
    """A level neighbour 0.1 m away horizontally, 0, 1 and 5 widths (1 L) above: 1 / (1 + (dz / L)^2) times the
    Gaussian decay along the horizontal distance; its x-offset copy carries the side (offset_x / L)."""
    dz = np.array([0.0, L, 5.0 * L])
    f = _f(np.column_stack([0.1 + 0 * dz, 0 * dz, dz]))
    along = np.exp(-((0.1 / (4.0 * L)) ** 2))
    np.testing.assert_allclose(f["side_c1L_e4L_1"], along / (1.0 + (dz / L) ** 2), rtol=1e-12)
    np.testing.assert_allclose(f["side_c1L_e4L_x_1"], f["side_c1L_e4L_1"] * 0.1 / L, rtol=1e-12)
    assert feature_group("side_c1L_e4L_1") == "side" and feature_group("above_g1L_i4L_1") == "above"


def test_the_algebraic_ground_proximity_is_half_at_its_scale() -> None:
    """1 / (1 + (h / s L)^2) at h = s L is 1/2, at h = 3 s L 1/10, for each scale; a target-only feature (no source)."""
    for scale in (0.4, 1.0, 2.5):
        name, _ = ground_names(scale, "inv")
        at = _f(np.array([[9.0, 0.0, 0.0]]), h_m=scale * L)[name][0]
        far = _f(np.array([[9.0, 0.0, 0.0]]), h_m=3.0 * scale * L)[name][0]
        assert abs(at - 0.5) < 1e-12 and abs(far - 0.1) < 1e-12
        assert feature_group(name) == "place"
