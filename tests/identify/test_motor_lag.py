"""Logs of COMMANDED motor thrust (a real flight controller's u[N]) reach the air through the motors'
lag: the manifest says so (``motor_thrust: commanded``) and the measurement compensates each
vehicle's Vehicle.motor_time_constant_s (proxplan.identify.loading.measure_options_for)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from proxplan.identify import synthetic_logs, write_synthetic_manifest
from proxplan.identify.data import IdentifyOptions
from proxplan.identify.loading import load_units
from proxplan.identify.manifest import load_manifest
from proxplan.identify.measure import MeasureOptions, motor_command_for_N, motor_lag_compensated_N
from proxplan.physics import BUILTIN_VEHICLES, EffectInputs, SourceSample, total_wrench

CF = BUILTIN_VEHICLES["crazyflie-2.1"]


def test_command_inverse_is_exact() -> None:
    rng = np.random.default_rng(0)
    delivered = 0.08 + 0.01 * np.cumsum(rng.normal(size=(300, 4)), axis=0) / 10
    cmd = motor_command_for_N(delivered, 0.01, 0.072)
    # the lag starts at rest at the first command; its start-up mismatch decays as exp(-t / tau)
    np.testing.assert_allclose(motor_lag_compensated_N(cmd, 0.01, 0.072)[300 // 2 :], delivered[300 // 2 :], atol=1e-9)


def test_interpolated_command_is_the_lag_of_a_ramp() -> None:
    """p = 1: the command runs linearly between samples; the lag of that ramp, integrated finely (1000 steps a
    sample, exact per fine step for the fine ramp), is what the discretisation gives; p = 0 holds each sample."""
    rng = np.random.default_rng(1)
    dt, tau, fine = 0.01, 0.05, 1000
    cmd = 0.08 + 0.02 * rng.normal(size=(60, 1))
    for p in (0.0, 0.5, 1.0):
        f, out = float(cmd[0, 0]), [float(cmd[0, 0])]
        h, a = dt / fine, np.exp(-dt / fine / tau)
        for k in range(1, len(cmd)):
            for j in range(fine):
                u = cmd[k - 1, 0] + p * (cmd[k, 0] - cmd[k - 1, 0]) * (j + 0.5) * h / dt
                f = a * f + (1 - a) * u
            out.append(f)
        got = motor_lag_compensated_N(cmd, dt, tau, interpolation=p)[:, 0]
        np.testing.assert_allclose(got, out, atol=2e-7)
    held = motor_lag_compensated_N(cmd, dt, tau)
    assert np.abs(motor_lag_compensated_N(cmd, dt, tau, interpolation=1.0) - held).max() > 1e-3


def _errors(tmp: Path, motor_thrust: str, motor_lag: bool = True) -> float:
    t = 0.01 * np.arange(1200)
    low = np.column_stack([0.1 * np.sin(1.3 * t), 0 * t, 0.6 + 0.05 * np.sin(9.0 * t)])
    high = np.column_stack([0 * t, 0 * t, 1.0 + 0 * t])
    logs = synthetic_logs(
        {"low": CF, "high": CF}, {"low": low, "high": high}, t, motor_time_constant_s=CF.motor_time_constant_s
    )
    flights = [("f_00", "train", logs), ("f_01", "test", logs)]
    manifest = write_synthetic_manifest(tmp / motor_thrust, flights, "crazyflie-2.1", motor_thrust=motor_thrust)
    opts = IdentifyOptions(measure=MeasureOptions(window_s=0.05, motor_lag=motor_lag))
    unit = next(
        u for u in load_units(load_manifest(manifest), options=opts).units if u.name == "low" and u.split == "test"
    )
    vel = np.gradient(low, t, axis=0)
    truth = total_wrench(EffectInputs(CF, low[:, 2], vel, (SourceSample(CF, low - high),)))[0]
    inner = slice(20, -20)
    return float(np.sqrt(np.mean((unit.force_N[inner, 2] - truth[inner, 2]) ** 2)))


def test_commanded_logs_are_measured_through_the_motor_lag(tmp_path: Path) -> None:
    compensated = _errors(tmp_path, "commanded")
    as_delivered = _errors(tmp_path, "delivered")
    switched_off = _errors(tmp_path / "off", "commanded", motor_lag=False)
    assert compensated < 0.1 * as_delivered, (compensated, as_delivered)
    assert switched_off == as_delivered
