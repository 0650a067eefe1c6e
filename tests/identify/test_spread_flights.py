"""The 90 % interval of a NEW flight (issue 35, stop 71): a per-flight constant in the residual (drawn here;
on the shipped flights its cause is not traced: docs/identify.md, stop 72) and the coverage judged with the flight as the unit (proxplan.identify.per_flight,
proxplan.identify.spread.fit_spread)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from proxplan.identify import synthetic_logs, write_synthetic_manifest
from proxplan.identify.data import Model
from proxplan.identify.loading import load_units
from proxplan.identify.manifest import load_manifest
from proxplan.identify.per_flight import (
    between_log_variance,
    coverage_interval,
    log_offset,
    new_flight_quantile,
    ratio_mean,
)
from proxplan.identify.spread import band_errors, fit_spread
from proxplan.physics import BUILTIN_VEHICLES, ResidualSpread, TypeSpread, spread_N

TYPE = "crazyflie-2.1"
OFFSET_SIGMA_N = 0.010
"""Spread of the drawn per-log thrust offset, N (about 1 g: the shipped flights' constant per log is 1-1.5 g)."""
REPLICATIONS = 24
"""Independent draws of (train flights, test flights): the mean coverage's standard error falls as 1/sqrt(24)."""
TRAIN_FLIGHTS = 2
TEST_FLIGHTS = 3


def test_ratio_mean_is_the_cluster_estimator() -> None:
    """Two clusters: p = sum y / sum n, Var = k/(k-1) sum (y - p n)^2 / (sum n)^2; one cluster: no variance."""
    p, var = ratio_mean([9.0, 5.0], [10.0, 10.0])
    assert p == pytest.approx(0.7)
    assert var == pytest.approx(2.0 * ((9.0 - 7.0) ** 2 + (5.0 - 7.0) ** 2) / 400.0)
    assert ratio_mean([9.0], [10.0])[1] == float("inf")


def test_coverage_interval_takes_the_flight_as_the_unit() -> None:
    """Three flights of 1 000 samples, 80, 90 and 100 % inside: the interval is p +- t_2 se (wide: three
    flights), it holds 90 %; one flight says nothing of the next (0..1); flights that agree give a narrow one."""
    ci = coverage_interval([800.0, 900.0, 1000.0], [1000.0, 1000.0, 1000.0])
    se = np.sqrt(1.5 * (100.0**2 + 0.0 + 100.0**2) / 3000.0**2)
    assert ci.coverage == pytest.approx(0.9) and ci.flights == 3
    assert ci.coverage - ci.low == pytest.approx(4.302653 * se, rel=1e-5) and ci.high == 1.0  # t, 2 dof, 97.5 %
    assert ci.holds(0.9) and ci.design_effect > 10.0  # samples of one flight are far from independent
    one = coverage_interval([700.0], [1000.0])
    assert (one.low, one.high) == (0.0, 1.0) and one.holds(0.9)
    tight = coverage_interval([700.0, 701.0, 699.0, 700.0], [1000.0] * 4)
    assert not tight.holds(0.9)


def test_between_log_variance_removes_the_means_own_noise() -> None:
    """Log means with no offset (white noise only): the between-log variance is about zero once each mean's own
    batch-means variance is taken off; with offsets of 10 mN it is about (10 mN)^2."""
    rng = np.random.default_rng(1)
    t_s = np.arange(0.0, 20.0, 0.01)
    noise_only = [log_offset(rng.normal(0.0, 0.01, t_s.size), np.ones(t_s.size), t_s) for _ in range(200)]
    assert between_log_variance(*zip(*noise_only)) < 0.01**2 / t_s.size  # under one mean's own variance
    offsets = rng.normal(0.0, 0.01, 200)
    with_offsets = [log_offset(b + rng.normal(0.0, 0.01, t_s.size), np.ones(t_s.size), t_s) for b in offsets]
    assert np.sqrt(between_log_variance(*zip(*with_offsets))) == pytest.approx(0.01, rel=0.15)  # 200 logs: 5 %


def test_new_flight_quantile_is_students() -> None:
    """All the residual a per-log constant (no within part): the multiplier is Student's t quantile at k
    degrees of freedom (the predictive law of a new draw), wider than the Gaussian 1.645 with few logs."""
    n = 1000
    q = new_flight_quantile(np.zeros(n), np.zeros(n), np.full(n, 0.01), np.full(n, 4.0), np.ones(n), 0.9)
    assert q == pytest.approx(2.131847, rel=1e-6)  # t_4, 95 %


def test_old_model_file_spread_reads_no_flight_part() -> None:
    """A spread saved before stop 71 (no flight_N) reads flight_N = 0 and gives the place sigma alone."""
    from proxplan.physics.model_file import ResidualSpreadPart

    part = ResidualSpreadPart.model_validate({"quantile_90": 1.7, "by_type": {TYPE: {"floor_N": 0.01}}})
    spread = part.spread()
    assert spread.by_type[TYPE].flight_N == 0.0
    x = np.array([[1.0, 0.0, 0.0, 0.0, 0.0, 0.0]])
    assert spread_N(spread.by_type[TYPE], x)[0] == pytest.approx(0.01)
    new = ResidualSpread(by_type={TYPE: TypeSpread(0.003, flight_N=0.004)})
    assert spread_N(new.by_type[TYPE], x)[0] == pytest.approx(0.005)  # sqrt(3^2 + 4^2) mN
    again = ResidualSpreadPart.model_validate(new.to_dict()).spread()
    assert again.by_type[TYPE].flight_N == pytest.approx(0.004)


def _flights(root: Path, count: int) -> list:
    """``count`` generated flights, Crazyflie 'b' in the jet of 'a' above it, each vehicle log with its own
    thrust offset drawn from N(0, OFFSET_SIGMA_N^2) (an unmodelled constant force) and noise."""
    veh = BUILTIN_VEHICLES[TYPE]
    rng = np.random.default_rng(35)
    t = np.arange(0.0, 6.0, 0.01)
    flights = []
    for k in range(count):
        a = np.column_stack([0.05 * np.sin(0.6 * t + k), 0.04 * np.cos(0.5 * t), 1.3 + 0 * t])
        b = np.column_stack([0.08 * np.sin(0.9 * t + 2 * k), 0.06 * np.sin(0.7 * t), 0.9 + 0.1 * np.sin(0.4 * t + k)])
        logs = {}
        for name in ("a", "b"):
            offset_N = float(rng.normal(0.0, OFFSET_SIGMA_N))

            def hidden(inputs, offset_N=offset_N):
                force = np.zeros((len(inputs.time_s), 3))
                force[:, 2] = offset_N
                return force, np.zeros_like(force)

            logs[name] = synthetic_logs({"a": veh, "b": veh}, {"a": a, "b": b}, t, accel_noise_mps2=0.03,
                                        motor_noise_N=0.002, seed=k, hidden_wrench=hidden)[name]  # fmt: skip
        flights.append((f"f{k:02d}", "train" if k % 2 else "test", logs))  # both splits: a valid manifest
    return flights


def test_the_interval_holds_on_new_flights_with_a_per_flight_offset(tmp_path: Path) -> None:
    """24 independent draws of 2 train flights (4 logs) and 3 test flights, each log with its own thrust offset
    (about 1 g) beside a fast part of about 0.15 g: the spread is fitted on the train flights' residual under
    the true model (nothing fitted: every residual is a new flight's) and the coverage counted on the test
    flights. Over the draws the mean coverage lies within 3 standard errors (of the 16 independent draws) of
    90 %. Taking the train samples' own 90 % quantile instead (main before stop 71) makes the interval the
    largest of the two logs' constants of each class, which covers a new log 2/3 of the time
    (docs/identify.md, stop 71: 0.67 +- 0.05 on these draws, against 0.88 +- 0.04 here)."""
    n_flights = REPLICATIONS * (TRAIN_FLIGHTS + TEST_FLIGHTS)
    manifest = load_manifest(write_synthetic_manifest(tmp_path, _flights(tmp_path, n_flights), TYPE))
    data = load_units(manifest)
    model = Model(vehicles=dict(data.types))
    per_flight: dict[str, list] = {}
    for u in data.units:
        per_flight.setdefault(u.flight, []).append(u)
    names = sorted(per_flight)
    coverage = []
    for r in range(REPLICATIONS):
        block = names[r * (TRAIN_FLIGHTS + TEST_FLIGHTS) : (r + 1) * (TRAIN_FLIGHTS + TEST_FLIGHTS)]
        train = [u for f in block[:TRAIN_FLIGHTS] for u in per_flight[f]]
        test = [u for f in block[TRAIN_FLIGHTS:] for u in per_flight[f]]
        acc = band_errors(test, model, fit_spread(train, model))["all"]
        coverage.append(acc.inside / acc.n_interval)
    mean, se = float(np.mean(coverage)), float(np.std(coverage, ddof=1) / np.sqrt(REPLICATIONS))
    assert 3.0 * se < 0.9 - 2.0 / 3.0, coverage  # the band below is narrow enough to tell 90 % from 2/3
    assert abs(mean - 0.9) < 3.0 * se, (mean, se, coverage)
