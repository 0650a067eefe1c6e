"""Time copies (lags, low-passes) named by their delay or time constant, on the grids and off them (issue 35)."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.physics import (
    BUILTIN_VEHICLES,
    FEATURE_NAMES,
    LAGS_S,
    LOWPASS_TAUS_S,
    TIME_KINDS,
    EffectInputs,
    SourceSample,
    feature_doc,
    feature_group,
    feature_matrix,
    is_feature,
    lagged,
    lowpass,
    parse_time_name,
    time_name,
)
from proxplan.physics.time_copies import TIME_FEATURE_SOURCES


def _inputs(seed: int, target: str, source: str, n: int = 300) -> tuple[EffectInputs, list]:
    """Two sources at random offsets and velocities, a clock with a gap (two time runs), random base wrenches."""
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.005, 0.015, n))
    t[n // 2 :] += 2.0
    sv = BUILTIN_VEHICLES[source]
    srcs = tuple(SourceSample(sv, rng.normal(0, 0.3, (n, 3)), rng.normal(0, 0.5, (n, 3))) for _ in range(2))
    inputs = EffectInputs(target=BUILTIN_VEHICLES[target], height_above_ground_m=rng.uniform(0.02, 1.5, n),
                          velocity_mps=rng.normal(0, 0.5, (n, 3)), sources=srcs, time_s=t,
                          position_m=rng.normal(0, 1, (n, 3)))  # fmt: skip
    return inputs, [(rng.normal(0, 0.1, (n, 3)), rng.normal(0, 0.01, (n, 3))) for _ in srcs]


def test_every_grid_copy_parses_back_and_builds_its_name() -> None:
    copies = [n for n in FEATURE_NAMES if parse_time_name(n) is not None]
    assert len(copies) == len(TIME_FEATURE_SOURCES) * (len(LAGS_S) + len(LOWPASS_TAUS_S))
    for name in copies:
        source, kind, seconds = parse_time_name(name)
        assert seconds in TIME_KINDS[kind] and time_name(source, kind, seconds) == name
    for name in ("base_fz_lag_N", "base_fz_lowpass_N", "above_jet_1", "above_jet_lag050ms_1", "above_jet_lag0ms_1",
                 "ground_exp_lag100ms_1", "above_jet_lp2p5ms_1"):  # fmt: skip
        assert parse_time_name(name) is None


def test_a_copy_off_the_grid_is_a_feature_computed_by_its_name() -> None:
    """lp 283 ms and lag 465 ms of the jet kernel times the relative speed: features (documented, in the temporal
    group of their source), and their columns the source's column filtered at those seconds."""
    inputs, base = _inputs(3, "small-quad", "small-quad")
    names = [
        time_name("above_jet_rel_speed_xy_mps", "lp", 0.283),
        time_name("above_jet_rel_speed_xy_mps", "lag", 0.465),
    ]
    assert names == ["above_jet_rel_speed_xy_lp283ms_mps", "above_jet_rel_speed_xy_lag465ms_mps"]
    assert not any(n in FEATURE_NAMES for n in names)
    assert all(is_feature(n) and feature_group(n) == "temporal:above" for n in names)
    assert "0.283" in feature_doc(names[0]) and "0.465" in feature_doc(names[1])
    x = feature_matrix(inputs, base, ["above_jet_rel_speed_xy_mps", *names])
    t = np.asarray(inputs.time_s)
    np.testing.assert_array_equal(x[:, 1], lowpass(x[:, 0], t, 0.283))
    np.testing.assert_array_equal(x[:, 2], lagged(x[:, 0], t, 0.465))


@pytest.mark.parametrize(("target", "source"), [("small-quad", "small-quad"), ("crazyflie-2.1", "small-quad")])
def test_the_whole_dictionary_is_bit_identical_to_its_grids(target: str, source: str) -> None:
    """The default dictionary's names are the sources' copies on the declared grids in the order they always had
    (sources, then lags, then low-passes), and every copy's column is exactly ``lagged`` / ``lowpass`` of its
    source's column at the grid's value (the loop over the grids the dictionary was built with before names off
    the grid parsed; checked against that version on these inputs too)."""
    old_names = [
        name for f in TIME_FEATURE_SOURCES
        for name in [*(time_name(f, "lag", s) for s in LAGS_S), *(time_name(f, "lp", s) for s in LOWPASS_TAUS_S)]
    ]  # fmt: skip
    assert [n for n in FEATURE_NAMES if parse_time_name(n) is not None] == old_names
    inputs, base = _inputs(11, target, source)
    whole = dict(zip(FEATURE_NAMES, feature_matrix(inputs, base).T))
    t = np.asarray(inputs.time_s)
    for f in TIME_FEATURE_SOURCES:
        for lag in LAGS_S:
            np.testing.assert_array_equal(whole[time_name(f, "lag", lag)], lagged(whole[f], t, lag))
        for tau in LOWPASS_TAUS_S:
            np.testing.assert_array_equal(whole[time_name(f, "lp", tau)], lowpass(whole[f], t, tau))
    alone = feature_matrix(inputs, base, ["above_core_lp400ms_1", "base_fz_lag169ms_N"])
    np.testing.assert_array_equal(alone[:, 0], whole["above_core_lp400ms_1"])
    np.testing.assert_array_equal(alone[:, 1], whole["base_fz_lag169ms_N"])
