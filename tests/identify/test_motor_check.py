"""The measurement checks itself (issue 29): the motor time constant that makes free-flight F_z the
steadiest tells whether the logs hold commanded or delivered thrust; a manifest that says otherwise
warns (JSON ``warnings`` and the report)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from proxplan.identify import synthetic_logs, write_synthetic_manifest
from proxplan.identify.data import IdentifyOptions
from proxplan.identify.loading import load_units
from proxplan.identify.manifest import load_manifest
from proxplan.identify.measure import MeasureOptions
from proxplan.identify.motor_check import check_loaded
from proxplan.physics import BUILTIN_VEHICLES

CF = BUILTIN_VEHICLES["crazyflie-2.1"]
OPTIONS = MeasureOptions(window_s=0.05)


def _manifest(tmp: Path, *, lagged: bool, declared: str) -> Path:
    """Two single-vehicle flights bobbing at 1-2 Hz well above the ground (free flight: no source, out
    of ground effect). ``lagged``: the logs hold COMMANDED thrust (first-order motors of the
    vehicle's tau turn it into the needed force); else the DELIVERED thrust."""
    t = 0.01 * np.arange(1500)
    flights = []
    for k in range(2):
        z = 0.8 + 0.03 * np.sin((7.0 + k) * t) + 0.01 * np.sin(13.0 * t + k)
        pos = np.column_stack([0.2 * np.sin(0.7 * t), 0 * t, z])
        logs = synthetic_logs({"a": CF}, {"a": pos}, t, accel_noise_mps2=0.01, seed=k,
                              motor_time_constant_s=CF.motor_time_constant_s if lagged else None)  # fmt: skip
        flights.append((f"f_{k:02d}", "train" if k == 0 else "test", logs))
    return write_synthetic_manifest(tmp / f"{lagged}_{declared}", flights, "crazyflie-2.1", motor_thrust=declared)


def _check(tmp: Path, *, lagged: bool, declared: str) -> dict:
    manifest = load_manifest(_manifest(tmp, lagged=lagged, declared=declared))
    data = load_units(manifest, options=IdentifyOptions(measure=OPTIONS), thrust_coefficient_samples=False)
    return check_loaded(data, motor_thrust=manifest.motor_thrust, options=OPTIONS)


@pytest.mark.parametrize("lagged", [True, False])
def test_right_declaration_agrees_wrong_one_warns(tmp_path: Path, lagged: bool) -> None:
    right, wrong = ("commanded", "delivered") if lagged else ("delivered", "commanded")
    ok = _check(tmp_path, lagged=lagged, declared=right)
    entry = ok["types"]["crazyflie-2.1"]
    assert ok["warnings"] == [] and entry["warning"] is None, ok
    if lagged:  # the lag the logs hold is found (grid 0.05 / 0.072 / 0.09 s around the truth 0.072 s)
        assert 0.05 <= entry["best_tau_s"] <= 0.09
    else:
        assert entry["best_tau_s"] == 0.0
    bad = _check(tmp_path, lagged=lagged, declared=wrong)
    assert len(bad["warnings"]) == 1 and "motor_thrust" in bad["warnings"][0], bad
    assert bad["types"]["crazyflie-2.1"]["spread_declared_N"] > 1.05 * bad["types"]["crazyflie-2.1"]["spread_best_N"]


def test_delivered_logs_read_as_commanded_warn_in_identify_json_and_report(tmp_path: Path, capsys) -> None:
    """The issue's case: a simulator's delivered thrust declared commanded; identify says so (stderr,
    JSON ``warnings``, report) instead of letting a false lag pass for an effect."""
    from proxplan.cli import main

    manifest = _manifest(tmp_path, lagged=False, declared="commanded")
    out = tmp_path / "out"
    assert main(["identify", str(manifest), "--out", str(out), "--json"]) == 0
    captured = capsys.readouterr()
    doc = json.loads(captured.out)
    assert len(doc["warnings"]) == 1 and doc["motor_lag_check"]["types"]["crazyflie-2.1"]["best_tau_s"] == 0.0
    assert "warning:" in captured.err and "motor_thrust" in captured.err
    assert "Motor lag check" in (out / "report.md").read_text()


def test_hover_with_command_noise_is_no_evidence_of_a_lag(tmp_path: Path) -> None:
    """Issue 35: a hovering vehicle whose logged (delivered) thrust carries noise the accelerometer never
    saw: a lag would smooth that noise and steady F_z, but smoothing is no delay. The check compares the
    lags by their phase only, so the rightly declared logs draw no warning."""
    t = 0.01 * np.arange(3000)
    flights = []
    for k in range(2):
        pos = np.column_stack([0 * t, 0 * t, 1.0 + 0.002 * np.sin(0.5 * t + k)])  # a hover, out of ground effect
        logs = synthetic_logs({"a": CF}, {"a": pos}, t, accel_noise_mps2=0.005, motor_noise_N=0.004, seed=k)
        flights.append((f"h_{k:02d}", "train" if k == 0 else "test", logs))
    manifest = load_manifest(write_synthetic_manifest(tmp_path, flights, "crazyflie-2.1", motor_thrust="delivered"))
    data = load_units(manifest, options=IdentifyOptions(measure=OPTIONS), thrust_coefficient_samples=False)
    check = check_loaded(data, motor_thrust="delivered", options=OPTIONS)
    entry = check["types"]["crazyflie-2.1"]
    assert check["warnings"] == [] and entry["warning"] is None, entry
    # every candidate lag keeps the noise's power: their spreads agree to a few percent
    spreads = np.array(list(entry["spread_N"].values()))
    assert spreads.max() < 1.05 * spreads.min(), entry["spread_N"]
