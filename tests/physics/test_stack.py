"""Several sources above one target (proxplan.physics.stack): shielding of an upper jet."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import integrate

from proxplan.physics import (
    BUILTIN_VEHICLES,
    EffectInputs,
    ModelOptions,
    SourceSample,
    base_wrench,
    disturbance_wrench,
    intercepted_flux_fraction,
    shielding_factors,
)
from proxplan.physics.geometry import Discretisation, frame_elements

CF = BUILTIN_VEHICLES["crazyflie-2.1"]
BIG = BUILTIN_VEHICLES["crazyflie-parrot"]


def test_flux_fraction_matches_a_direct_integral_of_the_gaussian_jet() -> None:
    """phi from the disk quadrature equals the share of rho V^2 through the four disks computed by
    2-D numerical integration of the (S0-2) profile over the disks, plus the frame elements."""
    dz = 0.5
    off = np.array([[0.09, -0.02, -dz]])
    phi = intercepted_flux_fraction(CF, CF, off)[0]
    a = max(dz - CF.downwash.z0_m, 0.5 * CF.size_m)
    c = CF.downwash.c_rad
    R = CF.propeller.radius_m
    total = np.pi * a * a / (2.0 * c)
    through = 0.0
    for rotor in CF.rotor_positions_m:
        cx, cy = off[0, 0] + rotor[0], off[0, 1] + rotor[1]

        def f(r: float, th: float, cx: float = cx, cy: float = cy) -> float:
            x, y = cx + r * np.cos(th), cy + r * np.sin(th)
            return np.exp(-2.0 * c * (x * x + y * y) / (a * a)) * r

        through += integrate.dblquad(f, 0.0, 2.0 * np.pi, 0.0, R)[0]
    frame = frame_elements(CF, Discretisation())
    r_sq = np.sum((frame.position_m[:, :2] + off[0, :2]) ** 2, axis=1)
    through += float(np.exp(-2.0 * c * r_sq / (a * a)) @ frame.area_m2)
    assert 0.05 < phi < 0.95
    assert phi == pytest.approx(through / total, rel=0.03)


def test_flux_fraction_is_zero_above_and_shrinks_with_distance() -> None:
    hub = intercepted_flux_fraction(CF, CF, np.array([[0.0, 0.0, -0.12]]))[0]  # narrow jet onto the hub
    near = intercepted_flux_fraction(CF, CF, np.array([[0.0, 0.0, -0.5]]))[0]
    far = intercepted_flux_fraction(CF, CF, np.array([[0.0, 0.0, -2.0]]))[0]
    aside = intercepted_flux_fraction(CF, CF, np.array([[0.5, 0.0, -0.15]]))[0]
    assert hub > 0.5
    assert intercepted_flux_fraction(CF, CF, np.array([[0.0, 0.0, 0.2]]))[0] == 0.0
    assert near > far > 0.0
    assert aside < 0.01 * near


def _stack_inputs(options: ModelOptions) -> EffectInputs:
    # target at the origin; middle 0.2 m above, upper 0.45 m above, slightly off-axis
    off_mid = np.array([[0.0, 0.0, -0.20], [0.02, 0.0, -0.20]])
    off_up = np.array([[0.01, 0.0, -0.45], [0.0, 0.03, -0.45]])
    return EffectInputs(
        target=CF,
        height_above_ground_m=np.full(2, 2.0),
        velocity_mps=np.zeros((2, 3)),
        sources=(SourceSample(BIG, off_up), SourceSample(CF, off_mid)),
        options=options,
    )


def test_upper_jet_is_scaled_by_what_the_middle_disks_do_not_ingest() -> None:
    inputs = _stack_inputs(ModelOptions(stack_shielding=1.0))
    f, _ = base_wrench(inputs)
    up, mid = inputs.sources
    phi = intercepted_flux_fraction(BIG, CF, up.offsets_m - mid.offsets_m)
    expect = disturbance_wrench(BIG, CF, up.offsets_m).force_N * (1.0 - phi)[:, None]
    expect += disturbance_wrench(CF, CF, mid.offsets_m).force_N
    np.testing.assert_allclose(f, expect, rtol=1e-12, atol=1e-15)
    # the per-pair sum (S0's superposition, eta = 0) is an upper bound of the stack's disturbance
    f0, _ = base_wrench(_stack_inputs(ModelOptions(stack_shielding=0.0)))
    assert np.all(np.abs(f[:, 2]) < np.abs(f0[:, 2]))


def test_one_source_overhead_is_s0_exactly() -> None:
    """The lower source is not shielded by the upper, and a source beside (not between) shields nothing."""
    off_mid = np.array([[0.0, 0.0, -0.2]])
    off_up = np.array([[0.0, 0.0, -0.45]])
    s_up, s_mid = shielding_factors([off_up, off_mid], [BIG, CF], 1.0)
    assert s_mid[0] == 1.0 and s_up[0] < 1.0
    off_below = np.array([[0.0, 0.0, 0.3]])  # the second vehicle is below the target: not between
    assert np.all(np.concatenate(shielding_factors([off_up, off_below], [BIG, CF], 1.0)) == 1.0)


def test_shielding_parameter_is_checked() -> None:
    with pytest.raises(ValueError, match="stack_shielding"):
        ModelOptions(stack_shielding=3.5)


def test_vectorised_factors_are_the_product_over_every_source_between() -> None:
    """shielding_factors (vectorised, skipping triples that provably multiply by 1.0) equals the
    definition s_j = prod_k max(1 - eta phi_jk, 0) over k between j and the target, evaluated one
    (j, k) pair at a time, on random stacks of mixed vehicles."""
    rng = np.random.default_rng(4)
    kinds = [CF, BIG, BUILTIN_VEHICLES["small-quad"], BUILTIN_VEHICLES["large-quad"]]
    sources = [kinds[i % 4] for i in range(7)]
    offs = [np.column_stack([rng.uniform(-0.6, 0.6, (300, 2)), rng.uniform(-1.5, 0.3, 300)]) for _ in sources]
    for eta in (0.7, 1.0, 2.5):
        got = shielding_factors(offs, sources, eta)
        for j, (oj, vj) in enumerate(zip(offs, sources)):
            want = np.ones(300)
            for k, (ok, vk) in enumerate(zip(offs, sources)):
                if k == j:
                    continue
                between = (-oj[:, 2] > 1e-6) & (-ok[:, 2] > 1e-6)
                phi = np.where(between, intercepted_flux_fraction(vj, vk, oj - ok), 0.0)
                want *= np.maximum(1.0 - eta * phi, 0.0)
            np.testing.assert_allclose(got[j], want, rtol=1e-14, atol=0.0)
        assert min(float(f.min()) for f in got) < 0.9  # some sources are shielded


def test_beyond_the_shielding_reach_the_factor_is_exactly_one() -> None:
    from proxplan.physics.stack import shielding_reach_m

    reach = shielding_reach_m(BIG, CF, 1.0, 1.2)
    assert 0.1 < reach < 2.0
    for dz in (0.05, 0.3, 0.8, 1.2):
        off_up = np.array([[0.0, 0.0, -dz - 0.3]])
        off_mid = np.array([[-reach * 1.001, 0.0, -0.3]])  # middle at the reach from the upper axis
        assert shielding_factors([off_up, off_mid], [BIG, CF], 1.0)[0][0] == 1.0
        assert intercepted_flux_fraction(BIG, CF, off_mid - off_up)[0] * 2.0**60 < 1.0
    assert shielding_reach_m(BIG, CF, 1.0, 2.0) > reach > shielding_reach_m(BIG, CF, 1.0, 0.3)


def test_pass_through_share_is_one_minus_eta_phi_to_the_last_bit() -> None:
    """Where the bound skips phi, 1 - eta phi would have rounded to exactly 1.0 anyway."""
    from proxplan.physics import pass_through_share

    rng = np.random.default_rng(5)
    off = np.column_stack([rng.uniform(-1.5, 1.5, (4000, 2)), rng.uniform(-2.0, 0.2, 4000)])
    for upper, middle in ((BIG, CF), (CF, BUILTIN_VEHICLES["large-quad"])):
        for eta in (0.5, 1.0, 3.0):
            want = np.maximum(1.0 - eta * intercepted_flux_fraction(upper, middle, off), 0.0)
            got = pass_through_share(upper, middle, off, eta)
            np.testing.assert_array_equal(got, want)
            assert 0.05 < float(np.mean(got < 1.0)) < 0.95  # both kinds of rows occur
