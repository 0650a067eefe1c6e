"""Delivered motor thrust from PWM and Vbat (proxplan.identify.thrust_map) on synthetic saturating logs."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from proxplan.identify.measure import MeasureOptions, measure_log, motor_lag_compensated_N
from proxplan.identify.synthetic_logs import SyntheticMotor, synthetic_logs
from proxplan.identify.thrust_map import (
    CEILING,
    FLOOR,
    IN_RANGE,
    MotorSamples,
    ThrustMap,
    delivered_thrust_N,
    fit_thrust_map,
    motor_limits,
    saturated_samples,
)
from proxplan.physics import BUILTIN_VEHICLES, EffectInputs, SourceSample, total_wrench

CF = BUILTIN_VEHICLES["crazyflie-2.1"]
MOTOR = SyntheticMotor()


LOW_BATTERY = SyntheticMotor(vbat_start_V=3.75, vbat_end_V=3.2, pwm_max=0.95)
"""Its ceiling falls from 0.144 N to 0.123 N per motor as the battery drains (x = 3.04 V at the end)."""


def _flight(amplitude_m: float, omega_radps: float, seed: int = 0, *, motor: SyntheticMotor = MOTOR,
            roll_torque_Nm: float = 0.0):  # fmt: skip
    """A Crazyflie 0.3 m below another, bobbing vertically hard enough (A w^2 > spare thrust) that
    its motors saturate on every up-stroke; returns the logs and the true force on the lower one.
    ``roll_torque_Nm`` adds a roll torque oscillation of that amplitude (a truth nobody models) that,
    on the down-strokes' low thrust, drives motors to their floor (the controller asks them for a
    negative force)."""
    t = 0.01 * np.arange(1500)
    low = np.column_stack([0.02 * np.sin(0.5 * t), 0 * t, 0.6 + amplitude_m * np.sin(omega_radps * t)])
    high = np.column_stack([0 * t, 0 * t, 0.9 + 0 * t])
    vehicles = {"low": CF, "high": CF}

    def roll(inputs):
        torque = np.zeros((inputs.n_samples, 3))
        torque[:, 0] = roll_torque_Nm * np.sin(2.3 * inputs.time_s)
        return np.zeros((inputs.n_samples, 3)), torque

    logs = synthetic_logs(vehicles, {"low": low, "high": high}, t, motor=motor, seed=seed, hidden_wrench=roll)
    vel = np.gradient(low, t, axis=0)
    inputs = EffectInputs(target=CF, height_above_ground_m=low[:, 2], velocity_mps=vel,
                          sources=(SourceSample(CF, low - high),))  # fmt: skip
    return logs, total_wrench(inputs, ())[0]


def _samples(log) -> MotorSamples:
    return MotorSamples(commanded_N=log.motor_thrust_N, pwm=log.motor_pwm, vbat_V=log.vbat_V)


def test_fit_recovers_the_motor_map() -> None:
    train, _ = _flight(0.07, 13.0)
    tmap = fit_thrust_map([_samples(train["low"]), _samples(train["high"])])
    x = np.linspace(2.0, 3.2, 20)
    np.testing.assert_allclose(tmap.thrust_N(x[:, None] / 4.0 * np.ones((1, 4)), np.full(20, 4.0))[:, 0],
                               MOTOR.thrust_N(x), rtol=0.02)  # fmt: skip
    assert tmap.usable
    assert tmap.max_thrust_N == pytest.approx(MOTOR.max_thrust_N, rel=0.05)
    assert ThrustMap.from_dict(tmap.to_dict(), "m").coef == pytest.approx(tmap.coef)


def test_delivered_thrust_recovers_the_disturbance_where_commanded_fails() -> None:
    train, _ = _flight(0.07, 13.0, seed=1)  # the map is fitted on another (train) flight
    tmap = fit_thrust_map([_samples(train["low"])])
    logs, truth = _flight(0.06, 14.0)
    low = logs["low"]
    sat = saturated_samples(tmap, _samples(low))
    assert 0.1 < sat.mean() < 0.6  # the test really saturates, and not always
    opts = MeasureOptions(window_s=0.03)
    commanded = measure_log(CF, low, options=opts).force_N[:, 2]
    delivered = measure_log(CF, replace(low, motor_thrust_N=delivered_thrust_N(tmap, _samples(low))), options=opts)
    inner = slice(10, -10)
    err_cmd = np.sqrt(np.mean((commanded - truth[:, 2])[inner] ** 2))
    err_del = np.sqrt(np.mean((delivered.force_N[:, 2] - truth[:, 2])[inner] ** 2))
    print(f"RMSE F_z delivered {err_del:.4g} N, commanded {err_cmd:.4g} N, saturated {sat.mean():.2f}")
    assert err_del < 0.2 * err_cmd, (err_del, err_cmd)
    assert err_del < 0.1 * np.sqrt(np.mean(truth[:, 2] ** 2))


def test_lagged_actual_thrust_is_not_taken_for_saturation() -> None:
    """Logs whose u[N] never exceeds the motor maximum (an actual thrust) flag nothing."""
    train, _ = _flight(0.05, 9.0)
    tmap = fit_thrust_map([_samples(train["low"])])
    s = _samples(train["low"])
    capped = replace(s, commanded_N=np.minimum(s.commanded_N, tmap.max_thrust_N))
    assert not saturated_samples(tmap, capped).any()


def test_saturated_outliers_below_the_ceiling_do_not_reject_the_map() -> None:
    """A few samples whose u[N] is far above what their PWM gives (a motor saturated just below the
    ceiling band) must not make an otherwise exact map 'unusable'; a map most samples disagree with is."""
    rng = np.random.default_rng(3)
    pwm = rng.uniform(0.3, 0.8, (4000, 4))
    vbat = np.full(4000, 4.0)
    good = MOTOR.thrust_N(pwm * 4.0)
    outliers = good.copy()
    outliers[:100] *= 8.0  # 2.5 % of samples: desired force ~8x the delivered one
    tmap = fit_thrust_map([MotorSamples(commanded_N=outliers, pwm=pwm, vbat_V=vbat)])
    assert tmap.usable, (tmap.r2, tmap.inlier_fraction)
    scrambled = rng.permutation(good.ravel()).reshape(good.shape)  # u[N] unrelated to PWM
    assert not fit_thrust_map([MotorSamples(commanded_N=scrambled, pwm=pwm, vbat_V=vbat)]).usable


def test_both_limits_floor_and_low_battery_ceiling() -> None:
    """Regression (issue 29): a motor asked for a NEGATIVE force sits at PWM 0 (delivers nothing) and a
    motor on a low battery stops below the full battery's ceiling (x 0.3 V under x_max). Both are found
    (no voltage band) and measured with the force their PWM gives; u[N] read as thrust is far off."""
    train, _ = _flight(0.07, 13.0, seed=1)  # the map is fitted on a full-battery train flight
    tmap = fit_thrust_map([_samples(train["low"]), _samples(train["high"])])
    logs, truth = _flight(0.06, 14.0, motor=LOW_BATTERY, roll_torque_Nm=4e-3)
    s = _samples(logs["low"])
    lim = motor_limits(tmap, s)
    x = s.pwm * s.vbat_V[:, None]
    assert np.all(lim[s.commanded_N < 0.0] == FLOOR) and (lim == FLOOR).sum() > 100
    assert ((lim == CEILING) & (x < tmap.x_max_V - 0.2)).sum() > 100  # the low battery's ceiling
    opts = MeasureOptions(window_s=0.03)
    commanded = measure_log(CF, logs["low"], options=opts).force_N[:, 2]
    delivered = measure_log(CF, replace(logs["low"], motor_thrust_N=delivered_thrust_N(tmap, s)), options=opts)
    for at in (np.any(lim == FLOOR, axis=1), np.any(lim == CEILING, axis=1)):
        err_cmd = np.sqrt(np.mean((commanded - truth[:, 2])[at] ** 2))
        err_del = np.sqrt(np.mean((delivered.force_N[:, 2] - truth[:, 2])[at] ** 2))
        assert err_del < 0.02 * err_cmd and err_del < 1e-3, (err_del, err_cmd)  # N


def test_lagged_actual_thrust_at_both_limits_is_never_a_limit() -> None:
    """A simulator's u[N] is the rotors' lagged ACTUAL thrust while PWM is the command: it trails the
    PWM by up to tens of mN on the same low-battery flight, but never asks for a force the motor gives
    nowhere within the window, so nothing is flagged and u[N] is kept."""
    train, _ = _flight(0.07, 13.0, seed=1)
    tmap = fit_thrust_map([_samples(train["low"])])
    logs, _ = _flight(0.06, 14.0, motor=LOW_BATTERY, roll_torque_Nm=4e-3)
    s = _samples(logs["low"])
    actual = motor_lag_compensated_N(LOW_BATTERY.thrust_N(s.pwm * s.vbat_V[:, None]), 0.01, 0.05)
    assert np.max(np.abs(actual - LOW_BATTERY.thrust_N(s.pwm * s.vbat_V[:, None]))) > 0.02  # really lags
    assert np.all(motor_limits(tmap, replace(s, commanded_N=actual)) == IN_RANGE)
