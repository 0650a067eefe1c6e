"""Predictions read through the measurement's smoothing (proxplan.identify.loading.smoothing_of_prediction):
the measured wrench is the Savitzky-Golay fit of the true one, so a vehicle that crosses a jet faster than
the window is measured with a flattened, widened peak; the prediction with S(p) - p added follows it."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from proxplan.identify import synthetic_logs, write_synthetic_manifest
from proxplan.identify.data import IdentifyOptions, Model, predict
from proxplan.identify.loading import load_units
from proxplan.identify.manifest import load_manifest
from proxplan.physics import BUILTIN_VEHICLES

CF = BUILTIN_VEHICLES["crazyflie-2.1"]


def _unit(tmp: Path, smoothed: bool):
    t = 0.01 * np.arange(1500)
    # the upper vehicle sweeps across the lower one at up to 1.5 m/s, 0.25 m above: a jet crossed in ~0.1 s
    high = np.column_stack([0.6 * np.sin(2.5 * t), 0 * t, 0.85 + 0 * t])
    low = np.column_stack([0 * t, 0 * t, 0.6 + 0 * t])
    logs = synthetic_logs({"low": CF, "high": CF}, {"low": low, "high": high}, t)
    flights = [("f_00", "train", logs), ("f_01", "test", logs)]
    manifest = write_synthetic_manifest(tmp / str(smoothed), flights, "crazyflie-2.1")
    data = load_units(load_manifest(manifest), options=IdentifyOptions(smoothed_prediction=smoothed),
                      thrust_coefficient_samples=False)  # fmt: skip
    unit = next(u for u in data.units if u.name == "low" and u.split == "test")
    return unit, Model(vehicles=data.types)


def test_prediction_through_the_smoothing_follows_the_measured_jet_crossings(tmp_path: Path) -> None:
    plain, model = _unit(tmp_path, smoothed=False)
    smoothed, _ = _unit(tmp_path, smoothed=True)
    assert plain.smoothing_force_N is None and smoothed.smoothing_force_N is not None
    inner = slice(50, -50)
    err_plain = float(np.sqrt(np.mean((plain.force_N[inner, 2] - predict(plain, model)[0][inner, 2]) ** 2)))
    err_smoothed = float(np.sqrt(np.mean((smoothed.force_N[inner, 2] - predict(smoothed, model)[0][inner, 2]) ** 2)))
    peak = float(np.max(np.abs(predict(plain, model)[0][:, 2])))
    assert err_plain > 0.02 * peak  # the crossings are fast enough for the window to matter
    assert err_smoothed < 0.25 * err_plain, (err_smoothed, err_plain)


def test_a_vehicle_with_no_source_gets_no_correction(tmp_path: Path) -> None:
    t = 0.01 * np.arange(400)
    alone = np.column_stack([0.3 * np.sin(t), 0 * t, 0.7 + 0 * t])
    logs = synthetic_logs({"alone": CF}, {"alone": alone}, t)
    manifest = write_synthetic_manifest(tmp_path, [("f_00", "train", logs), ("f_01", "test", logs)], "crazyflie-2.1")
    data = load_units(load_manifest(manifest), options=IdentifyOptions(), thrust_coefficient_samples=False)
    assert all(u.smoothing_force_N is None for u in data.units)
