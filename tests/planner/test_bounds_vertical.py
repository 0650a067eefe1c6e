"""The premises of a crossing-rate bound through the vertical force (issue 37, round 16D; docs/planner.md,
"Stop 54, round 16D"), and the throughput bound's ``packing`` argument.

A source's jet only pushes a target down (F_z <= 0) and does nothing to a target not below it; the
motors' mean thrust change is -F_z / 4, so one source's vertical force alone bounds the authority
usage from below. These are what a bound "through the vertical force" would rest on; they are tested
here on the built-in types so that a change to the model that breaks them fails."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.physics import BUILTIN_VEHICLES, authority_usage, disturbance_wrench
from proxplan.planfile import scenario_from_dict
from proxplan.planner import bounds
from proxplan.planner.formations import DEFAULT_TYPES, LAYOUTS

PAIRS = [(s, t) for s in DEFAULT_TYPES for t in DEFAULT_TYPES]


def _offsets(seed: int, n: int = 400) -> np.ndarray:
    """Random p_target - p_source (n, 3), m: horizontal within 0.8 m, target 0.5 m above to 3 m below."""
    rng = np.random.default_rng(seed)
    r = 0.8 * np.sqrt(rng.random(n))
    phi = rng.uniform(0.0, 2.0 * np.pi, n)
    dz = rng.uniform(-0.5, 3.0, n)  # positive: the target below the source
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), -dz])


@pytest.mark.parametrize(("source", "target"), PAIRS)
def test_a_source_only_pushes_down_and_only_below_it(source, target):
    s, t = BUILTIN_VEHICLES[source], BUILTIN_VEHICLES[target]
    off = _offsets(PAIRS.index((source, target)))
    fz = disturbance_wrench(s, t, off).force_N[:, 2]
    assert np.all(fz <= 0.0)
    assert np.all(fz[-off[:, 2] <= 0.0] == 0.0)  # the target level with or above the source: nothing
    assert np.any(fz < 0.0)  # the jet does act below (the draw is not all out of reach)


@pytest.mark.parametrize(("source", "target"), PAIRS)
def test_one_sources_vertical_force_bounds_the_usage_from_below(source, target):
    """usage >= |F_z| / (4 headroom up): the largest motor change is at least the mean, -F_z / 4."""
    s, t = BUILTIN_VEHICLES[source], BUILTIN_VEHICLES[target]
    w = disturbance_wrench(s, t, _offsets(7))
    usage = authority_usage(t, w.force_N, w.torque_Nm)
    up = t.max_thrust_per_rotor_N - t.hover_thrust_per_rotor_N
    vertical = -w.force_N[:, 2] / (4.0 * up)
    assert np.all(usage >= vertical * (1.0 - 1e-12))
    assert np.any(vertical > 0.0)


def test_throughput_packing_argument_orders_the_bound():
    """The bound falls as the packing number grows, the separation sphere's count (the default) gives
    the default, and with K = 1 (one at a time) it is at least every crosser's slab time added."""
    sc = scenario_from_dict(LAYOUTS["corridor"](16))
    slab = next(s for s in bounds.slabs(sc) if s.axis == 0)
    one = bounds.throughput_time_s(sc, slab, packing=1)
    two = bounds.throughput_time_s(sc, slab, packing=2)
    assert one > two > 0.0
    tau = sum((slab.hi_m - slab.lo_m) / t.kinematic_limits.max_speed_mps for t in sc.vehicles.values())
    assert one >= tau
    assert bounds.throughput_time_s(sc, slab, packing=len(sc.vehicles)) == 0.0  # never more than K crossers
    assert bounds.throughput_time_s(sc, slab) == 0.0  # the separation sphere alone: hundreds fit
