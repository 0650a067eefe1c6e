"""The multi-scale kernels (proxplan.physics.basis): names that hold their scales, on the grid and off it."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.physics import BUILTIN_VEHICLES, FEATURE_NAMES, EffectInputs, SourceSample, feature_matrix
from proxplan.physics.basis import AXES, BASIS_PLACES, BasisKernel, basis_kernels, parse_basis_name
from proxplan.physics.feature_terms import parse_term_key
from proxplan.physics.features import feature_doc, feature_group, is_feature

VEH = BUILTIN_VEHICLES["small-quad"]
L = VEH.size_m


def _inputs(offsets: np.ndarray, source_velocity_mps: np.ndarray | None = None) -> EffectInputs:
    n = len(offsets)
    v = np.zeros((n, 3)) if source_velocity_mps is None else source_velocity_mps
    return EffectInputs(target=VEH, height_above_ground_m=np.full(n, 1.0), velocity_mps=np.zeros((n, 3)),
                        sources=(SourceSample(VEH, offsets, v),))  # fmt: skip


def test_every_grid_kernel_name_parses_back_to_its_kernel() -> None:
    names = 0
    for where in BASIS_PLACES:
        for kernel in basis_kernels(where):
            for axis in AXES:
                name = kernel.name(axis)
                assert name in FEATURE_NAMES and parse_basis_name(name) == (kernel, axis)
                names += 1
    assert names == sum(1 for n in FEATURE_NAMES if parse_basis_name(n) is not None)
    assert parse_basis_name("above_jet_1") is None and parse_basis_name("ground_exp_1") is None


def test_a_kernel_off_the_grid_is_computed_by_its_name() -> None:
    """A neighbour straight above at three depths, and 0.1 m aside: exp(-(r / 0.774 L)^2) exp(-dz / 2.31 L), named
    with its scales; its x copy and its relative-speed copy; a term key on it parses; nothing of it is on the grid."""
    depth = np.array([0.5 * L, 2.0 * L, 5.0 * L])
    off = np.column_stack([0.1 + 0 * depth, 0 * depth, -depth])  # p_target - p_source: the source above
    kernel = BasisKernel("above", "g", 0.774, "e", 2.31)
    names = [kernel.name(a) for a in AXES]
    assert names[0] == "above_g0p774L_e2p31L_1" and not any(n in FEATURE_NAMES for n in names)
    assert all(is_feature(n) and feature_group(n) == "above" and "0.774" in feature_doc(n) for n in names)
    moving = np.tile([0.3, -0.4, 0.0], (3, 1))  # the source's velocity: relative horizontal speed 0.5 m/s
    x = feature_matrix(_inputs(off, moving), [(np.zeros((3, 3)), np.zeros((3, 3)))], names)
    expected = np.exp(-((0.1 / (0.774 * L)) ** 2) - depth / (2.31 * L))
    np.testing.assert_allclose(x[:, 0], expected, rtol=1e-12)
    np.testing.assert_allclose(x[:, 1], expected * 0.1 / L, rtol=1e-12)
    np.testing.assert_allclose(x[:, 3], expected * 0.5, rtol=1e-12)
    assert parse_term_key(f"force_z_N*W*{names[0]}") == ("force_z_N", names[0])


def test_a_grid_kernel_asked_alone_equals_its_column_of_the_whole_dictionary() -> None:
    rng = np.random.default_rng(5)
    off = rng.normal(0.0, 0.2, (50, 3))
    base = [(np.zeros((50, 3)), np.zeros((50, 3)))]
    whole = dict(zip(FEATURE_NAMES, feature_matrix(_inputs(off), base).T))
    for name in ("side_c2p5L_e1L_y_1", "below_g0p4L_i4L_rel_speed_xy_mps", "above_g1L_e4L_1"):
        np.testing.assert_array_equal(feature_matrix(_inputs(off), base, [name])[:, 0], whole[name])


@pytest.mark.parametrize(
    "name", ["side_g1L_i4L_1", "above_l1L_e4L_1", "above_g0L_e4L_1", "above_g1L_e4L_z_1", "nope_1"]
)
def test_a_name_no_family_declares_is_refused(name: str) -> None:
    """Beside the target the decay along is Gaussian only; above, the profile Gaussian only; scales positive."""
    assert parse_basis_name(name) is None and not is_feature(name)
    with pytest.raises(ValueError, match="not a feature"):
        feature_matrix(_inputs(np.zeros((2, 3))), [(np.zeros((2, 3)), np.zeros((2, 3)))], [name])
    with pytest.raises(ValueError):
        parse_term_key(f"force_z_N*W*{name}")
