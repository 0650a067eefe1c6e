"""Cutoff map: shape of r_cut(dz), consistency with `proxplan wrench`, invalid-zone rules, any level."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from proxplan.costmaps import INVALID_RULES, build_cutoff_map, r_cut_from_usage
from proxplan.physics import BUILTIN_VEHICLES, VALIDITY_FACTOR_L, authority_usage, disturbance_wrench

SMALL, LARGE = BUILTIN_VEHICLES["small-quad"], BUILTIN_VEHICLES["large-quad"]
CF = BUILTIN_VEHICLES["crazyflie-2.1"]


@pytest.fixture(scope="module")
def small_over_large():
    return build_cutoff_map(SMALL, LARGE)


@pytest.fixture(scope="module")
def large_over_small():
    return build_cutoff_map(LARGE, SMALL)


def _max_usage_over_azimuth(source, target, r_m, dz_m, n_azimuth=46):
    """Direct-model usage at radius r, depth dz, maximised over a dense azimuth sweep of [0, 2 pi)."""
    phi = np.linspace(0.0, 2.0 * math.pi, n_azimuth, endpoint=False)
    offsets = np.column_stack([r_m * np.cos(phi), r_m * np.sin(phi), np.full_like(phi, -dz_m)])
    batch = disturbance_wrench(source, target, offsets)
    return float(authority_usage(target, batch.force_N, batch.torque_Nm).max())


def test_r_cut_non_decreasing_in_valid_zone_small_over_large(small_over_large):
    """Non-decreasing in dz while the jet's peak usage stays clearly above the level.

    Deeper, the peak usage (~1/dz, thrust change S0-6) decays towards the level, so the contour of
    usage = level closes and r_cut falls back to 0: that is where and why it decreases (test below)."""
    cmap = small_over_large
    level = 0.02
    valid = cmap.valid
    dz = cmap.dz_m[valid]
    r = cmap.r_cut_m(dz, level=level)
    peak = cmap.usage[:, valid].max(axis=0)
    rising = dz <= dz[np.argmax(r)]  # up to the widest point of the contour
    assert dz[rising][-1] > 2.0  # covers the docking-relevant range and well beyond
    assert np.all(np.diff(r[rising]) >= -1e-3), "r_cut decreases in the valid zone before its maximum"
    beyond = ~rising
    assert np.all(np.diff(r[beyond]) <= 1e-3)
    assert peak[np.argmax(r)] > level


def test_r_cut_within_half_size_and_a_few_metres(small_over_large, large_over_small):
    for cmap, source, target in ((small_over_large, SMALL, LARGE), (large_over_small, LARGE, SMALL)):
        for level in cmap.levels:
            r = cmap.r_cut_m(cmap.dz_m[cmap.valid], level=level)
            positive = r[r > 0]
            if positive.size:
                assert positive.max() < 3.0
                # a disturbed target is further out than the smaller vehicle's half-size once the
                # contour is open, except where it closes (deepest nodes before dropping to zero)
                assert np.median(positive) > min(source.arm_length_m, target.arm_length_m)
    r_low = small_over_large.r_cut_m(np.array([0.5, 1.0, 2.0]), level=0.02)
    assert np.all(r_low > max(SMALL.arm_length_m, LARGE.arm_length_m))


@pytest.mark.parametrize("level", [0.02, 0.05])
def test_consistent_with_direct_wrench_just_inside_and_outside(small_over_large, level):
    cmap = small_over_large
    for dz in (0.5, 1.0, 1.5):
        r_cut = float(cmap.r_cut_m(np.array(dz), level=level))
        assert r_cut > 0.0
        delta = max(0.01, 0.03 * r_cut)
        assert _max_usage_over_azimuth(SMALL, LARGE, r_cut - delta, dz) >= level
        assert _max_usage_over_azimuth(SMALL, LARGE, r_cut + delta, dz) < level


def test_consistent_with_proxplan_wrench_cli(large_over_small, capsys):
    from proxplan.cli import main

    cmap = large_over_small
    level, dz = 0.1, 1.2
    r_cut = float(cmap.r_cut_m(np.array(dz), level=level))
    delta = max(0.01, 0.03 * r_cut)
    usages = {}
    for name, r in (("inside", r_cut - delta), ("outside", r_cut + delta)):
        best = 0.0
        for phi in np.linspace(0.0, 0.25 * math.pi, 7):
            code = main(["wrench", "--source", "large-quad", "--target", "small-quad", "--offset",
                         str(r * math.cos(phi)), str(r * math.sin(phi)), str(-dz), "--json"])  # fmt: skip
            assert code == 0
            best = max(best, json.loads(capsys.readouterr().out)["authority_usage"])
        usages[name] = best
    assert usages["inside"] >= level > usages["outside"]


def test_invalid_zone_is_never_silently_zero(small_over_large):
    cmap = small_over_large
    inside = np.linspace(0.01, cmap.validity_dz_m, 20)
    for level in (0.02, 0.5, 2.0):  # 2.0: never reached anywhere, still not zero in the invalid zone
        model = cmap.r_cut_m(inside, level=level, invalid_rule="model")
        conservative = cmap.r_cut_m(inside, level=level, invalid_rule="conservative")
        forbid = cmap.r_cut_m(inside, level=level, invalid_rule="forbid")
        assert np.all(conservative >= cmap.overlap_radius_m - 1e-12)
        assert np.all(conservative >= model - 1e-12)
        assert np.all(forbid >= conservative - 1e-12)
        assert np.ptp(forbid) == 0.0
    assert cmap.invalid_rule == "conservative"
    assert cmap.validity_dz_m == pytest.approx(VALIDITY_FACTOR_L * SMALL.size_m)
    # just below the boundary the conservative value is at least the first valid value
    first_valid = float(cmap.r_cut_m(np.array(cmap.validity_dz_m + 1e-6), level=0.02))
    assert float(cmap.r_cut_m(np.array(cmap.validity_dz_m), level=0.02)) >= first_valid - 1e-3
    with pytest.raises(ValueError):
        cmap.r_cut_m(inside, invalid_rule="ignore")


def test_zero_above_source_and_any_level(small_over_large):
    cmap = small_over_large
    assert np.all(cmap.r_cut_m(np.array([-1.0, -0.1, 0.0]), level=0.02) == 0.0)
    dz = cmap.dz_m
    for i, level in enumerate(cmap.levels):
        assert np.allclose(cmap.r_cut_m(dz, level=level), cmap.r_cut_levels_m[i])
    # levels not stored are answered from the usage grid and nest between stored ones
    r_lo, r_mid, r_hi = (cmap.r_cut_m(dz[cmap.valid], level=v) for v in (0.02, 0.03, 0.05))
    assert np.all(r_lo >= r_mid - 1e-12) and np.all(r_mid >= r_hi - 1e-12)
    assert np.any(r_lo > r_mid) and np.any(r_mid > r_hi)
    assert np.array_equal(cmap.default_r_cut_m, cmap.r_cut_m(dz, level=cmap.default_level))
    with pytest.raises(ValueError):
        cmap.r_cut_m(dz, level=0.0)


def test_r_cut_from_usage_interpolates_outermost_crossing():
    r = np.linspace(0.0, 1.0, 11)[:, None] * np.ones((1, 3))
    usage = np.zeros((11, 3))
    usage[:, 0] = np.exp(-((r[:, 0] / 0.4) ** 2))  # falls through 0.5 between nodes
    usage[:, 1] = 0.0  # never reaches the level
    usage[:, 2] = 1.0  # reaches it at the last node
    out = r_cut_from_usage(r, usage, 0.5)
    exact = 0.4 * math.sqrt(math.log(2.0))
    assert out[0] == pytest.approx(exact, abs=0.01)
    assert out[1] == 0.0 and out[2] == 1.0


def test_build_rejects_bad_options():
    with pytest.raises(ValueError):
        build_cutoff_map(SMALL, LARGE, invalid_rule="zero")
    with pytest.raises(ValueError):
        build_cutoff_map(SMALL, LARGE, levels=(0.001,))
    assert set(INVALID_RULES) == {"conservative", "model", "forbid"}


@pytest.mark.parametrize("source_name", list(BUILTIN_VEHICLES))
def test_every_shipped_pair_brackets_the_level(source_name):
    """Shipped maps of every pair: direct-model usage < level just outside r_cut, and >= level just
    inside wherever the usage contour is not closing between two dz nodes."""
    from proxplan.costmaps import pair_maps

    source = BUILTIN_VEHICLES[source_name]
    for target in BUILTIN_VEHICLES.values():
        cmap = pair_maps(source, target).cutoff
        for level in cmap.levels:
            for dz in np.linspace(cmap.validity_dz_m * 1.05, 3.0, 5):
                r_cut = float(cmap.r_cut_m(np.array(dz), level=level))
                if r_cut <= 0.02:
                    continue
                delta = max(0.01, 0.03 * r_cut)
                assert _max_usage_over_azimuth(source, target, r_cut + delta, dz) < level, (target.name, level, dz)
                # inside: only where the contour is not closing within this dz cell (there the
                # lookup takes the larger bracketing node on purpose, see proxplan.costmaps.cutoff)
                k = np.searchsorted(cmap.dz_m, dz) - 1
                spread = abs(np.subtract(*cmap.r_cut_m(cmap.dz_m[k : k + 2], level=level)))
                if spread < 0.5 * delta:
                    assert _max_usage_over_azimuth(source, target, r_cut - delta, dz) >= level, (target.name, level, dz)
