"""Issue 38: identify on the logs vehicles write (Crazyflie uSD, ROS 2 bags, PX4 ULog).

Each format's test file is written by the real library where it has a writer (rosbags) and from the
format's published description otherwise (uSD: proxplan.identify.formats.usdlog; ULog:
tests/identify/log_writers.py); it reads back to the same samples within float precision, and
identify on a two-vehicle flight in that format gives the same figures as on the same flight in the
canonical layout (forces logged)."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml

from proxplan.identify import IdentifyOptions, run_identify, synthetic_logs, write_canonical_csv
from proxplan.identify.flightlog import VehicleEntry
from proxplan.identify.formats import read_usdlog, read_vehicle_log, write_usdlog
from proxplan.identify.formats.contract import firmware_columns
from proxplan.identify.pwm_thrust import foerster_map
from proxplan.physics import BUILTIN_VEHICLES, Effect
from tests.identify.log_writers import write_pose_log_bag, write_ulog

TYPE = "crazyflie-2.1"
VEH = BUILTIN_VEHICLES[TYPE]
FAST = IdentifyOptions(effects=("thrust_bias",), discover=False)  # the comparison needs the pipeline, not its search
FIELDS = ("position_m", "velocity_mps", "accel_mps2", "quat_xyzw", "gyro_radps")


def _with_pwm(log, k: int):
    """``log`` with battery voltage (4.0 -> 3.7 V) and the PWM (whole counts) that the Foerster map turns
    into its forces; the forces are then what that PWM gives (quantised)."""
    vbat = np.linspace(4.0 - 0.02 * k, 3.7, len(log))
    c0, c1, c2 = foerster_map().coef[:3]
    f = np.clip(log.motor_thrust_N, c0, None)
    x = (-c1 + np.sqrt(c1 * c1 - 4.0 * c2 * (c0 - f))) / (2.0 * c2)
    pwm = np.round(x / vbat[:, None] * 65536.0) / 65536.0
    return replace(log, motor_pwm=pwm, vbat_V=vbat, motor_thrust_N=foerster_map().thrust_N(pwm, vbat))


def _flights():
    """Two flights (f0 train, f1 test) of 'a' hovering 0.3-0.5 m above a bobbing 'b', 8 s at 100 Hz."""
    t = np.arange(0.0, 8.0, 0.01)
    out = []
    for k in range(2):
        ph = 0.7 * k
        a = np.column_stack([0.03 * np.sin(t + ph), 0 * t, 1.2 + 0 * t])
        b = np.column_stack([0.05 * np.sin(0.8 * t + ph), 0 * t, 0.8 + 0.1 * np.sin(0.9 * t + ph)])
        logs = synthetic_logs({"a": VEH, "b": VEH}, {"a": a, "b": b}, t, accel_noise_mps2=0.02, seed=k,
                              effects=(Effect("thrust_bias", {"force_z_N": 0.01}),))  # fmt: skip
        out.append((f"f{k}", "train" if k == 0 else "test", {n: _with_pwm(log, k) for n, log in logs.items()}))
    return out


def _manifest(root: Path, fmt: str, logs: dict, extra: dict | None = None) -> Path:
    flights = [{"name": name, "split": split, "vehicles": {v: {"type": TYPE, "log": p, **(extra or {}).get(v, {})}
                                                           for v, p in vs.items()}} for name, split, vs in logs]  # fmt: skip
    path = root / f"{fmt}.yaml"
    path.write_text(yaml.safe_dump({"format": fmt, "root": ".", "motor_thrust": "delivered", "flights": flights}))
    return path


def _canonical_copy(root: Path, flight_logs: list) -> Path:
    """The same flights in the canonical layout, forces logged (no PWM): what the format's reader gave."""
    entries = []
    for name, split, logs in flight_logs:
        paths = {}
        for v, log in logs.items():
            paths[v] = f"{name}_{v}.csv.gz"
            write_canonical_csv(replace(log, motor_pwm=None, vbat_V=None, thrust_logged=True), root / paths[v])
        entries.append((name, split, paths))
    return _manifest(root, "canonical", entries)


def _with_map(flight_logs: list, tmap) -> list:
    """The read-back flights with the forces the pipeline's thrust map ``tmap`` gives their PWM."""
    return [(n, s, {v: replace(log, motor_thrust_N=tmap.thrust_N(log.motor_pwm, log.vbat_V)) for v, log in r.items()})
            for n, s, r in flight_logs]  # fmt: skip


def _figures(manifest: Path) -> dict:
    r = run_identify(manifest, options=FAST, thrust_summary=False)
    return {"before": r.before.to_json(), "calibrated": r.calibrated.to_json(), "after": r.after.to_json(),
            "selected": r.selected, "sources": {n: d["thrust_source"] for n, d in r.measurement_json()["saturation"].items()},
            "maps": r.thrust_maps}  # fmt: skip


def _same_figures(a: dict, b: dict) -> None:
    for key in ("before", "calibrated", "after"):
        for metric, value in a[key].items():
            assert b[key][metric] == pytest.approx(value, rel=1e-6, abs=1e-9), (key, metric)  # N, N m
    assert a["selected"] == b["selected"]


@pytest.fixture(scope="module")
def flights():
    return _flights()


@pytest.mark.parametrize("version", [1, 2])
def test_usdlog_reads_back_the_same_samples(tmp_path: Path, flights, version: int) -> None:
    log = flights[0][2]["b"]
    path = write_usdlog(tmp_path / "b.usd", {"fixedFrequency": (log.t_s, firmware_columns(log))}, version=version)
    usd = read_usdlog(path)
    assert usd.version == version and not usd.truncated and list(usd.events) == ["fixedFrequency"]
    back = read_vehicle_log(VehicleEntry("b", TYPE, path))
    np.testing.assert_allclose(back.t_s, log.t_s, atol=1e-9)  # 1 ms (v1) / 1 us (v2) steps hold 10 ms exactly
    for name in FIELDS:  # float32 in the file: ~1e-7 relative
        np.testing.assert_allclose(getattr(back, name), getattr(log, name), rtol=1e-5, atol=2e-6, err_msg=name)
    np.testing.assert_array_equal(back.motor_pwm, log.motor_pwm)  # whole counts
    np.testing.assert_allclose(back.vbat_V, log.vbat_V, rtol=1e-7)
    assert not back.thrust_logged  # no force in a uSD log: the published map gives it, the same to float32
    np.testing.assert_allclose(back.motor_thrust_N, log.motor_thrust_N, rtol=1e-6)


def test_usdlog_cut_mid_record_is_read_up_to_the_cut(tmp_path: Path, flights, proxplan) -> None:
    log = flights[0][2]["b"]
    path = write_usdlog(tmp_path / "b.usd", {"fixedFrequency": (log.t_s, firmware_columns(log))})
    data = path.read_bytes()
    cut = tmp_path / "cut.usd"
    cut.write_bytes(data[: len(data) - 4 - 30])  # the CRC and 30 bytes of the last record (96 bytes) gone
    usd = read_usdlog(cut)
    assert usd.truncated and "CRC32" in usd.note and "partial record" in usd.note
    assert len(usd.events["fixedFrequency"].t_s) == len(log) - 1
    res = proxplan("logs", cut, "--json")
    assert res.returncode == 0, res.stderr
    doc = json.loads(res.stdout)["logs"][0]
    assert doc["truncated"] and doc["vehicles"][0]["missing"] == []
    assert doc["vehicles"][0]["streams"][0]["samples"] == len(log) - 1


def test_usdlog_identify_gives_the_canonical_figures(tmp_path: Path, flights) -> None:
    entries, back = [], []
    for name, split, logs in flights:
        paths, read = {}, {}
        for v, log in logs.items():
            paths[v] = f"{name}_{v}.usd"
            write_usdlog(tmp_path / paths[v], {"fixedFrequency": (log.t_s, firmware_columns(log))})
            read[v] = read_vehicle_log(VehicleEntry(v, TYPE, tmp_path / paths[v]))
        entries.append((name, split, paths))
        back.append((name, split, read))
    usd = _figures(_manifest(tmp_path, "usdlog", entries))
    tmap = usd["maps"][TYPE]  # the published map, its scale checked in free flight ('a': nobody above it)
    assert set(usd["sources"].values()) == {"pwm_published_map_free_flight_scale"}
    weight = VEH.mass_kg * 9.81  # the logs follow the published map exactly, plus a hidden 0.01 N bias
    assert tmap.scale == pytest.approx(weight / (weight - 0.01), rel=0.003)
    canonical = _figures(_canonical_copy(tmp_path, _with_map(back, tmap)))
    _same_figures(canonical, usd)
    assert set(canonical["sources"].values()) == {"logged_u"}
    assert usd["after"]["rmse_fz_N"] < 0.8 * usd["before"]["rmse_fz_N"]  # the hidden thrust bias is found


LOG_VARS = ["stateEstimate.vx", "stateEstimate.vy", "stateEstimate.vz", "acc.x", "acc.y", "acc.z",
            "gyro.x", "gyro.y", "gyro.z", "motor.m1", "motor.m2", "motor.m3", "motor.m4", "pm.vbat"]  # fmt: skip


def _topics(name: str) -> dict:
    return {"topics": {"pose": f"/{name}/pose", "log": [{"topic": f"/{name}/log1", "vars": LOG_VARS}]}}


@pytest.mark.parametrize("storage", ["mcap", "sqlite3"])
def test_rosbag_reads_back_and_identifies_like_canonical(tmp_path: Path, flights, storage: str) -> None:
    entries, back = [], []
    for name, split, logs in flights:
        bag = tmp_path / f"{name}_bag"
        cols = {v: (log.t_s + 100.0, {k: c for k, (_, c) in firmware_columns(log).items()}) for v, log in logs.items()}
        write_pose_log_bag(bag, cols, storage=storage, vars_=LOG_VARS)
        read = {v: read_vehicle_log(VehicleEntry(v, TYPE, bag, topics=_topics(v)["topics"])) for v in logs}
        for v, log in logs.items():  # the bag's clock (ns) is shared by both vehicles
            np.testing.assert_allclose(read[v].t_s, log.t_s + 100.0, atol=1e-8)
            for f in FIELDS:
                np.testing.assert_allclose(getattr(read[v], f), getattr(log, f), rtol=1e-9, atol=1e-9, err_msg=f)
            np.testing.assert_array_equal(read[v].motor_pwm, log.motor_pwm)
        entries.append((name, split, {v: bag.name for v in logs}))
        back.append((name, split, read))
        if storage == "sqlite3":
            break
    if storage == "sqlite3":
        return  # the read-back holds for both storages; identify once (mcap)
    bag_fig = _figures(_manifest(tmp_path, "rosbag", entries, {v: _topics(v) for v in ("a", "b")}))
    _same_figures(_figures(_canonical_copy(tmp_path, _with_map(back, bag_fig["maps"][TYPE]))), bag_fig)


FAC, THRUST_MAX_N = 0.3, 0.16  # PX4 thrust model factor and full-command thrust of the ULog vehicle


def _ulog_topics(log) -> dict:
    """``log`` as PX4 ULog topics (NED / FRD), its motor commands from PX4's thrust model."""
    from scipy.spatial.transform import Rotation

    flip = np.array([1.0, -1.0, -1.0])
    rel = np.clip(log.motor_thrust_N / THRUST_MAX_N, 0.0, 1.0)
    c = (-(1 - FAC) + np.sqrt((1 - FAC) ** 2 + 4 * FAC * rel)) / (2 * FAC)
    body = Rotation.from_quat(log.quat_xyzw).inv().apply(log.accel_mps2) * flip
    q = log.quat_xyzw
    us = np.round(log.t_s * 1e6)
    return {
        "vehicle_local_position": (us, {"x": log.position_m[:, 0], "y": -log.position_m[:, 1], "z": -log.position_m[:, 2],
                                        "vx": log.velocity_mps[:, 0], "vy": -log.velocity_mps[:, 1], "vz": -log.velocity_mps[:, 2]}),
        "vehicle_attitude": (us, {"q": np.column_stack([q[:, 3], q[:, 0], -q[:, 1], -q[:, 2]])}),
        "vehicle_angular_velocity": (us, {"xyz": log.gyro_radps * flip}),
        "sensor_combined": (us, {"accelerometer_m_s2": body}),
        "actuator_motors": (us, {"control": np.column_stack([c, np.zeros((len(log), 8))])}),
        "battery_status": (us, {"voltage_v": log.vbat_V}),
    }  # fmt: skip


def _ulog_of(log, path: Path) -> Path:
    return write_ulog(path, _ulog_topics(log), {"THR_MDL_FAC": FAC})


def test_ulog_reads_back_and_identifies_like_canonical(tmp_path: Path, flights) -> None:
    entries, back = [], []
    for name, split, logs in flights:
        paths, read = {}, {}
        for v, log in logs.items():
            paths[v] = f"{name}_{v}.ulg"
            read[v] = read_vehicle_log(VehicleEntry(v, TYPE, _ulog_of(log, tmp_path / paths[v])))
            for f in FIELDS:
                np.testing.assert_allclose(getattr(read[v], f), getattr(log, f), rtol=1e-5, atol=2e-6, err_msg=f)
            assert read[v].thrust_shape == f"px4-thrust-model:{FAC:g}"
        entries.append((name, split, paths))
        back.append((name, split, read))
    ulog = _figures(_manifest(tmp_path, "ulog", entries))
    tmap = ulog["maps"][TYPE]
    assert ulog["sources"] == {"a": "pwm_free_flight_scale", "b": "pwm_free_flight_scale"}
    # the free-flight scale finds the vehicle's full-command thrust (free flight: 'a', nobody above it),
    # times weight / (weight - bias): a constant free-flight force (the hidden 0.01 N thrust bias) is
    # indistinguishable from a thrust scale there, and goes into it
    weight = VEH.mass_kg * 9.81
    assert tmap.thrust_at_N(np.array(1.0)) == pytest.approx(THRUST_MAX_N * weight / (weight - 0.01), rel=0.003)
    _same_figures(_figures(_canonical_copy(tmp_path, _with_map(back, tmap))), ulog)


def _one_line(capsys, code: int, *needles: str) -> None:
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    for n in needles:
        assert n in err, err


def test_bad_logs_are_one_line_errors_and_write_nothing(tmp_path: Path, flights, capsys) -> None:
    from proxplan.cli import main

    junk = tmp_path / "junk.usd"
    junk.write_bytes(b"\x00\x01 no log at all")
    _one_line(capsys, main(["logs", str(junk)]), str(junk))
    m = _manifest(tmp_path, "usdlog", [("f0", "train", {"a": "junk.usd"}), ("f1", "test", {"a": "junk.usd"})])
    _one_line(capsys, main(["identify", str(m), "--out", str(tmp_path / "o1")]), str(junk), "usdlog")
    log = flights[0][2]["a"]
    write_pose_log_bag(tmp_path / "bag", {"cf1": (log.t_s, {k: c for k, (_, c) in firmware_columns(log).items()})},
                             vars_=LOG_VARS)  # fmt: skip
    m = _manifest(
        tmp_path, "rosbag", [("f0", "train", {"cf9": "bag"}), ("f1", "test", {"cf9": "bag"})], {"cf9": _topics("cf9")}
    )
    _one_line(capsys, main(["identify", str(m), "--out", str(tmp_path / "o2")]), "topic /cf9/pose not in the bag")
    no_motors = tmp_path / "no_motors.ulg"  # a ULog of every topic but actuator_motors
    write_ulog(no_motors, {k: v for k, v in _ulog_topics(log).items() if k != "actuator_motors"}, {"THR_MDL_FAC": FAC})
    m = _manifest(tmp_path, "ulog", [("f0", "train", {"a": "no_motors.ulg"}), ("f1", "test", {"a": "no_motors.ulg"})])
    _one_line(capsys, main(["identify", str(m), "--out", str(tmp_path / "o3")]), "no_motors.ulg", "actuator_motors")
    # two vehicles whose logs never overlap in time (the second one's clock 100 s later)
    usd = {v: write_usdlog(tmp_path / f"{v}.usd", {"fixedFrequency": (lg.t_s, firmware_columns(lg))}).name
           for v, lg in flights[0][2].items()}  # fmt: skip
    m = _manifest(tmp_path, "usdlog", [("f0", "train", usd), ("f1", "test", usd)], {"b": {"time_offset_s": 100.0}})
    _one_line(capsys, main(["identify", str(m), "--out", str(tmp_path / "o4")]), "do not overlap in time")
    assert not any((tmp_path / f"o{k}").exists() for k in range(1, 5))


def test_logs_writes_a_manifest_evaluate_accepts(tmp_path: Path, flights, capsys) -> None:
    from proxplan.cli import main
    from proxplan.identify import load_manifest

    paths = []
    for name, _, logs in flights:
        for v, log in logs.items():
            paths.append(str(write_usdlog(tmp_path / f"{v}_{name[1:].zfill(2)}.usd",
                                          {"fixedFrequency": (log.t_s, firmware_columns(log))})))  # fmt: skip
    out = tmp_path / "sub" / "manifest.yaml"
    out.parent.mkdir()
    assert main(["logs", *paths, "--manifest", str(out), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert len(doc["logs"]) == 4 and all(d["format"] == "usdlog v2" for d in doc["logs"])
    v = doc["logs"][0]["vehicles"][0]
    assert (
        v["missing"] == [] and v["mapping"]["acc_x"] == "acc.x" and v["streams"][0]["rate_hz"] == pytest.approx(100.0)
    )
    assert out.read_text().startswith("# yaml-language-server: $schema=")
    manifest = load_manifest(out)
    assert [f.split for f in manifest.flights] == ["train", "test"] and manifest.format == "usdlog"
    assert {v.name for f in manifest.flights for v in f.vehicles} == {"a", "b"}


def test_clock_offset_found_by_cross_correlation_with_mocap(tmp_path: Path, flights) -> None:
    """A uSD log on a boot clock 37.123 s ahead: the mocap track puts it back within the reported error."""
    from proxplan.identify import load_manifest
    from proxplan.identify.loading import load_units

    name, split, logs = flights[0]
    paths = {}
    for v, log in logs.items():
        late = log.take(np.arange(150, len(log)))  # the log starts 1.5 s into the track
        shifted = replace(late, t_s=late.t_s + 37.123)  # on the vehicle's own clock
        paths[v] = write_usdlog(
            tmp_path / f"{v}.usd", {"fixedFrequency": (shifted.t_s, firmware_columns(shifted))}
        ).name
        track = np.column_stack([log.t_s, log.position_m])  # the motion-capture system's clock
        np.savetxt(tmp_path / f"{v}_mocap.csv", track, delimiter=",", header="t_s,x_m,y_m,z_m", comments="")
    extra = {v: {"mocap_log": f"{v}_mocap.csv"} for v in logs}
    m = _manifest(tmp_path, "usdlog", [("f0", "train", paths), ("f1", "test", paths)], extra)
    data = load_units(load_manifest(m), options=FAST, thrust_coefficient_samples=False)
    for v in logs:
        e = data.exclusions["f0"][v]
        assert e["alignment"] == "mocap" and 0.0 < e["alignment_error_s"] < 0.01
        assert abs(e["time_offset_s"] + 37.123) <= e["alignment_error_s"]
