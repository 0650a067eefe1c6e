"""Which pairs the verifier evaluates (proxplan.verify.reach): candidate rows equal a brute-force
search, counts above are exact, a pair beyond its reach is negligible, the grid's bound holds."""

from __future__ import annotations

import math

import numpy as np
import pytest

from proxplan.costmaps import pair_wrench
from proxplan.physics import BUILTIN_VEHICLES, ModelOptions, load_model_file, motor_thrust_changes_N
from proxplan.verify.reach import NEGLIGIBLE_USAGE, counts_above, pairs_within, usage_grid
from tests.conftest import REPO

TYPES = [BUILTIN_VEHICLES[k] for k in ("crazyflie-2.1", "crazyflie-parrot", "small-quad", "large-quad")]


def _q(source, target, off, effects=()):
    """The bound of the usage change of leaving the source out, as verify.reach defines it, -."""
    f, t = pair_wrench(source, target, off, ModelOptions(), effects)
    head = min(
        target.max_thrust_per_rotor_N - target.hover_thrust_per_rotor_N,
        target.hover_thrust_per_rotor_N - target.min_motor_thrust_N,
    )
    return np.abs(motor_thrust_changes_N(target, f, t)).max(axis=1) / head


def test_pairs_within_equals_a_brute_force_search():
    rng = np.random.default_rng(1)
    n, m = 30, 70
    xy = np.cumsum(rng.normal(0.0, 0.08, (n, m, 2)), axis=1) + rng.uniform(-2.0, 2.0, (n, 1, 2))
    radius = rng.uniform(0.2, 1.2, (n, n))
    radius = np.maximum(radius, radius.T)
    radius[3, 7] = radius[7, 3] = np.inf
    i, j, k = pairs_within(xy, radius)
    got = set(zip(i.tolist(), j.tolist(), k.tolist()))
    d = np.hypot(*(xy[:, None] - xy[None, :]).transpose(3, 0, 1, 2))  # (N, N, M)
    want = {(a, b, s) for a in range(n) for b in range(a + 1, n) for s in range(m) if d[a, b, s] <= radius[a, b]}
    assert got == want and len(i) == len(got)
    assert any(a == 3 and b == 7 for a, b, _ in got)


def test_counts_above_are_exact_at_the_threshold():
    rng = np.random.default_rng(2)
    base = rng.choice([1.0, 1.0 + 1e-6, 1.0 + 2e-6, 1.5, 1.5 - 1e-6, 0.3], size=(40, 60))
    z = base + np.where(rng.random((40, 60)) < 0.3, rng.normal(0.0, 3e-7, (40, 60)), 0.0)
    w = rng.random((40, 60)) < 0.5
    above = (z[None, :, :] - z[:, None, :]) > 1e-6  # [target, source, sample]
    np.testing.assert_array_equal(counts_above(z), above.sum(axis=1))
    np.testing.assert_array_equal(counts_above(z, w), (above & w[None]).sum(axis=1))


@pytest.mark.parametrize("with_effects", [False, True])
def test_beyond_the_reach_a_source_is_negligible(with_effects):
    effects = ()
    if with_effects:
        effects = load_model_file(REPO / "examples" / "models" / "neural-swarm.yaml").between_vehicle_effects
    rng = np.random.default_rng(3)
    for source in TYPES[:3]:
        for target in TYPES[:3]:
            grid = usage_grid(source, target, ModelOptions(), effects, dz_lo_m=0.0, dz_hi_m=1.1, r_max_m=8.0)
            assert 0.05 < grid.reach_m < 4.0
            r = grid.reach_m * rng.uniform(1.0, 3.0, 3000)
            a = rng.uniform(0.0, 2.0 * math.pi, 3000)
            dz = rng.uniform(1e-9, 1.25, 3000)  # the grid covers dz up to 1.25 m (a multiple of 0.25 m)
            off = np.column_stack([r * np.cos(a), r * np.sin(a), -dz])
            assert float(_q(source, target, off, effects=effects).max()) < NEGLIGIBLE_USAGE


def test_the_grids_bound_holds_between_its_nodes():
    """UsageGrid.bound at (r - tube, [dz - tube, dz + tube]) is at least q at every offset of that
    box (the tracking-tube check's screen): random boxes, checked at random points inside."""
    rng = np.random.default_rng(4)
    tube = 0.06
    for source, target in ((TYPES[0], TYPES[1]), (TYPES[3], TYPES[2]), (TYPES[1], TYPES[1])):
        grid = usage_grid(source, target, ModelOptions(), (), dz_lo_m=0.0, dz_hi_m=1.0 + tube, r_max_m=8.0)
        r = rng.uniform(0.0, 1.2 * grid.reach_m, 400)
        dz = rng.uniform(1e-3, 1.0, 400)
        lo, hi = np.maximum(dz - tube, 1e-3), dz + tube
        bound = grid.bound(np.maximum(r - tube, 0.0), lo, hi)
        for _ in range(5):  # points of each box: horizontally between r - tube and r, any azimuth
            rr = r - rng.uniform(0.0, tube, 400)
            zz = rng.uniform(lo, hi)
            a = rng.uniform(0.0, 2.0 * math.pi, 400)
            q = _q(source, target, np.column_stack([rr * np.cos(a), rr * np.sin(a), -zz]))
            assert np.all(q <= bound)
        # a bound, not a blanket, where it matters: below NEGLIGIBLE_USAGE the verifier drops a source anyway
        # (and the bound is floored at the physics' profile cut-off, 2e-22 of the peak, where q is 0)
        relevant = q > NEGLIGIBLE_USAGE
        assert relevant.sum() > 20 and np.median(bound[relevant] / q[relevant]) < 1e6
