"""Flight-log reading, canonical writer round trip, manifest and quality checks."""

from __future__ import annotations

import gzip
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml

from proxplan.fileio import UserError
from proxplan.identify.flightlog import FlightEntry, VehicleEntry, load_flight
from proxplan.identify.log_checks import QualityOptions, check_log
from proxplan.identify.manifest import load_manifest
from proxplan.identify.vehicle_log import NEURAL_SWARM_COLUMNS, VehicleLog, read_log, write_canonical_csv
from proxplan.physics import BUILTIN_VEHICLES

CF = BUILTIN_VEHICLES["crazyflie-2.1"]


def _log(n: int = 300, t0: float = 0.0, z: float = 1.0) -> VehicleLog:
    t = t0 + 0.01 * np.arange(n)
    rng = np.random.default_rng(1)
    return VehicleLog(
        t_s=t,
        position_m=np.column_stack([np.sin(t), np.cos(t), z + 0 * t]),
        velocity_mps=rng.normal(size=(n, 3)),
        accel_mps2=rng.normal(size=(n, 3)) + [0, 0, 9.81],
        quat_xyzw=np.tile([0.0, 0.0, 0.0, 1.0], (n, 1)),
        motor_thrust_N=np.full((n, 4), CF.hover_thrust_per_rotor_N),
        gyro_radps=rng.normal(size=(n, 3)),
    )


def _write_ns(path: Path, log: VehicleLog, *, drop: str | None = None) -> None:
    """A Neural-Swarm layout file (time in microseconds) with extra columns."""
    cols = [c for c in NEURAL_SWARM_COLUMNS.values()] + ["Vbat[V]"]
    table = np.column_stack([log.as_table(), np.full(len(log), 3.9)])
    table[:, 0] *= 1e6
    if drop:
        k = cols.index(drop)
        cols.pop(k)
        table = np.delete(table, k, axis=1)
    body = "\n".join(",".join(f"{v:.9g}" for v in row) for row in table)
    path.write_bytes(gzip.compress(("# " + ",".join(cols) + "\n" + body + "\n").encode()))


def test_canonical_round_trip(tmp_path: Path) -> None:
    log = _log()
    back = read_log(write_canonical_csv(log, tmp_path / "a.csv.gz"))
    np.testing.assert_allclose(back.as_table(), log.as_table(), rtol=1e-7, atol=1e-9)


def test_neural_swarm_microseconds_and_missing_column(tmp_path: Path) -> None:
    log = _log()
    _write_ns(tmp_path / "cf.csv.gz", log)
    back = read_log(tmp_path / "cf.csv.gz")
    np.testing.assert_allclose(back.t_s, log.t_s, atol=1e-8)  # microseconds -> seconds
    _write_ns(tmp_path / "bad.csv.gz", log, drop="wz[rad/s]")
    with pytest.raises(UserError, match=r"bad.csv.gz.*wz\[rad/s\]"):
        read_log(tmp_path / "bad.csv.gz")


def test_time_backwards_is_error_with_row() -> None:
    log = _log()
    t = log.t_s.copy()
    t[100] = t[98]
    with pytest.raises(UserError, match="row 101"):
        check_log(
            VehicleLog(
                t,
                *[
                    getattr(log, k)
                    for k in ("position_m", "velocity_mps", "accel_mps2", "quat_xyzw", "motor_thrust_N", "gyro_radps")
                ],
            ),
            weight_N=CF.weight_N,
        )


def test_nan_gap_and_ground_are_counted() -> None:
    log = _log(400)
    acc = log.accel_mps2.copy()
    acc[50:53] = np.nan  # a short NaN run
    pos = log.position_m.copy()
    pos[300:, 2] = 0.01  # sits on the ground for the last 100 samples
    t = log.t_s.copy()
    t[200:] += 0.5  # a gap
    bad = VehicleLog(t, pos, log.velocity_mps, acc, log.quat_xyzw, log.motor_thrust_N, log.gyro_radps)
    clean, ex = check_log(bad, weight_N=CF.weight_N, ground_z_m=0.0)
    assert ex.nan_rows == 3 and ex.ground_samples == 100 and ex.gap_segments >= 1
    assert len(clean) == 400 - 3 - 100 - ex.short_segment_samples - ex.impact_samples
    assert len(np.unique(clean.segment)) >= 2  # the gap splits the log
    assert np.all(np.isfinite(clean.as_table()))


def _bounce(v_impact_mps: float, n: int = 300) -> VehicleLog:
    """Falls at ``v_impact_mps`` onto the ground (z = 0) at sample 150, stays 5 samples, rises again."""
    t = 0.01 * np.arange(n)
    z = np.abs(t - 1.5) * v_impact_mps + 0.005
    vz = np.where(t < 1.5, -v_impact_mps, v_impact_mps)
    log = _log(n)
    return replace(log, position_m=np.column_stack([0 * t, 0 * t, z]),
                   velocity_mps=np.column_stack([0 * t, 0 * t, vz]))  # fmt: skip


def test_ground_impact_is_guarded_and_splits_the_log() -> None:
    """A fall onto the floor at 1 m/s: the samples within impact_guard_s of the contact are dropped
    (the bounce's force spreads through the smoothing and the mocap latency), the log is split there;
    a touch at 0.1 m/s (a landing) guards nothing."""
    clean, ex = check_log(_bounce(1.0), weight_N=CF.weight_N)
    guard_samples = 2 * int(round(QualityOptions().impact_guard_s / 0.01))
    assert ex.impacts == 1 and abs(ex.impact_samples - guard_samples) <= 2, ex
    assert len(np.unique(clean.segment)) == 2  # before and after the bounce
    assert np.min(np.abs(clean.t_s - 1.5)) > QualityOptions().impact_guard_s - 0.005
    slow, ex_slow = check_log(_bounce(0.1), weight_N=CF.weight_N)
    assert ex_slow.impacts == 0 and ex_slow.impact_samples == 0
    assert len(slow) == 300 - ex_slow.ground_samples - ex_slow.short_segment_samples


def test_non_overlapping_flight_is_error_and_overlap_trimmed(tmp_path: Path) -> None:
    write_canonical_csv(_log(300, 0.0), tmp_path / "a.csv")
    write_canonical_csv(_log(300, 10.0), tmp_path / "b.csv")
    write_canonical_csv(_log(300, 1.0), tmp_path / "c.csv")
    veh = {"a": CF, "b": CF, "c": CF}
    entry = FlightEntry(
        "f",
        "train",
        (
            VehicleEntry("a", "crazyflie-2.1", tmp_path / "a.csv"),
            VehicleEntry("b", "crazyflie-2.1", tmp_path / "b.csv"),
        ),
    )
    with pytest.raises(UserError, match="do not overlap"):
        load_flight(entry, veh)
    entry = FlightEntry(
        "f",
        "train",
        (
            VehicleEntry("a", "crazyflie-2.1", tmp_path / "a.csv"),
            VehicleEntry("c", "crazyflie-2.1", tmp_path / "c.csv"),
        ),
    )
    fl = load_flight(entry, veh)
    assert fl.exclusions["a"].outside_overlap_samples == 100 and fl.exclusions["c"].outside_overlap_samples == 100
    assert fl.logs["a"].t_s[0] >= 1.0 - 1e-9


def test_manifest_root_relative_to_file_and_errors(tmp_path: Path) -> None:
    (tmp_path / "data").mkdir()
    sub = tmp_path / "m"
    sub.mkdir()
    doc = {"format": "canonical", "root": "../data", "flights": [
        {"name": "a", "split": "train", "vehicles": {"x": {"type": "crazyflie-2.1", "log": "x.csv"}}},
        {"name": "b", "split": "test", "vehicles": {"x": {"type": "crazyflie-2.1", "log": "y.csv", "ground_z_m": 0.05}}}]}  # fmt: skip
    (sub / "m.yaml").write_text(yaml.safe_dump(doc))
    man = load_manifest(sub / "m.yaml")
    assert man.flights[0].vehicles[0].log.resolve() == (tmp_path / "data" / "x.csv").resolve()
    assert man.flights[1].vehicles[0].ground_z_m == 0.05
    doc["flights"][1]["split"] = "valid"
    (sub / "m.yaml").write_text(yaml.safe_dump(doc))
    with pytest.raises(UserError, match=r"flights\[1\]\.split"):
        load_manifest(sub / "m.yaml")
    doc["flights"].append(
        {"name": "v", "split": "validation", "vehicles": {"x": {"type": "crazyflie-2.1", "log": "z.csv"}}}
    )
    doc["flights"][1]["split"] = "test"
    (sub / "m.yaml").write_text(yaml.safe_dump(doc))
    assert [f.split for f in load_manifest(sub / "m.yaml").flights] == ["train", "test", "validation"]
    doc["flights"][1]["split"] = "train"
    (sub / "m.yaml").write_text(yaml.safe_dump(doc))
    with pytest.raises(UserError, match="test"):
        load_manifest(sub / "m.yaml")


def test_pwm_and_vbat_columns_read_and_optional(tmp_path: Path) -> None:
    from dataclasses import replace

    log = _log()
    n = len(log)
    pwm = np.linspace(0.5, 0.9, 4 * n).reshape(n, 4)
    vbat = np.linspace(4.1, 3.6, n)
    cols = list(NEURAL_SWARM_COLUMNS.values()) + ["u1[PWM]", "u2[PWM]", "u3[PWM]", "u4[PWM]", "Vbat[V]"]
    table = np.column_stack([log.as_table(), pwm, vbat])
    table[:, 0] *= 1e6
    body = "\n".join(",".join(f"{v:.9g}" for v in row) for row in table)
    (tmp_path / "p.csv.gz").write_bytes(gzip.compress(("# " + ",".join(cols) + "\n" + body + "\n").encode()))
    back = read_log(tmp_path / "p.csv.gz")
    assert back.has_pwm
    np.testing.assert_allclose(back.motor_pwm, pwm, rtol=1e-8)
    np.testing.assert_allclose(back.vbat_V, vbat, rtol=1e-8)
    assert back.take(np.arange(5)).motor_pwm.shape == (5, 4)
    # canonical layout: optional columns round-trip; without them the log has no PWM
    canon = read_log(write_canonical_csv(replace(log, motor_pwm=pwm, vbat_V=vbat), tmp_path / "c.csv.gz"))
    np.testing.assert_allclose(canon.motor_pwm, pwm, rtol=1e-8)
    assert not read_log(write_canonical_csv(log, tmp_path / "d.csv.gz")).has_pwm
    _write_ns(tmp_path / "nopwm.csv.gz", log)  # Vbat only: no PWM
    assert not read_log(tmp_path / "nopwm.csv.gz").has_pwm


def test_manifest_score_false_and_all_false(tmp_path: Path) -> None:
    doc = {"format": "canonical", "root": ".", "flights": [
        {"name": "a", "split": "train", "vehicles": {"x": {"type": "crazyflie-2.1", "log": "x.csv", "score": False},
                                                     "y": {"type": "crazyflie-2.1", "log": "y.csv"}}},
        {"name": "b", "split": "test", "vehicles": {"x": {"type": "crazyflie-2.1", "log": "x.csv"}}}]}  # fmt: skip
    path = tmp_path / "m.yaml"
    path.write_text(yaml.safe_dump(doc))
    m = load_manifest(path)
    assert [v.score for v in m.flights[0].vehicles] == [False, True]
    doc["flights"][0]["vehicles"]["y"]["score"] = "no"
    path.write_text(yaml.safe_dump(doc))
    with pytest.raises(UserError, match=r"vehicles\.y\.score"):
        load_manifest(path)
    for f in doc["flights"]:
        for v in f["vehicles"].values():
            v["score"] = False
    path.write_text(yaml.safe_dump(doc))
    with pytest.raises(UserError, match="score: false"):
        load_manifest(path)
    only_test = {**doc, "flights": [doc["flights"][1] | {"vehicles": {"x": {"type": "crazyflie-2.1", "log": "x"}}}]}
    path.write_text(yaml.safe_dump(only_test))
    with pytest.raises(UserError, match="train and one test"):
        load_manifest(path)
    assert len(load_manifest(path, require_train_and_test=False).flights) == 1
