"""Plan reader, truth YAML, Neural-Swarm log writer and manifest, and the `proxplan simulate` CLI."""

from __future__ import annotations

import gzip
import json
from pathlib import Path

import numpy as np
import pytest

from proxplan.fileio import UserError
from proxplan.flightsim import (
    NEURAL_SWARM_HEADER,
    hover_stack_plan,
    load_truth_file,
    simulate_plan,
    swap_plan,
    truth_from_dict,
    write_flight_logs,
)
from proxplan.planfile import read_plan, write_plan

REPO = Path(__file__).resolve().parents[2]
SHARED = REPO.parent / "shared"


def _plan_dict(plan):
    return {
        "scenario": plan.scenario,
        "dt_s": plan.dt_s,
        "metrics": {},
        "vehicles": {
            n: {
                "type": t.type_name,
                "t_s": t.t_s.tolist(),
                "position_m": t.position_m.tolist(),
                "velocity_mps": t.velocity_mps.tolist(),
                "acceleration_mps2": t.acceleration_mps2.tolist(),
            }
            for n, t in plan.vehicles.items()
        },
    }


def _write_plan(tmp_path, plan) -> Path:
    d = tmp_path / "plan"
    d.mkdir()
    (d / "plan.json").write_text(json.dumps(_plan_dict(plan)))
    return d / "plan.json"


def test_plan_reader_round_trip_and_errors(tmp_path):
    plan = hover_stack_plan(duration_s=1.0)
    path = _write_plan(tmp_path, plan)
    back = read_plan(path)
    assert set(back.vehicles) == {"top", "bottom"}
    np.testing.assert_allclose(back.vehicles["top"].position_m, plan.vehicles["top"].position_m)
    bad = _plan_dict(plan)
    bad["vehicles"]["top"]["position_m"] = bad["vehicles"]["top"]["position_m"][:-1]
    (tmp_path / "bad.json").write_text(json.dumps(bad))
    with pytest.raises(UserError, match=r"vehicles.top.position_m: expected 51 rows"):
        read_plan(tmp_path / "bad.json")
    (tmp_path / "broken.json").write_text("{")
    with pytest.raises(UserError, match="not valid JSON"):
        read_plan(tmp_path / "broken.json")
    bad2 = _plan_dict(plan)
    del bad2["vehicles"]["bottom"]["acceleration_mps2"]
    (tmp_path / "bad2.json").write_text(json.dumps(bad2))
    with pytest.raises(UserError, match="acceleration_mps2: missing"):
        read_plan(tmp_path / "bad2.json")


def test_truth_files_and_validation(tmp_path):
    for path in sorted((REPO / "examples" / "truth").glob("*.yaml")):
        spec = load_truth_file(path)
        assert spec.effects, path
    spec = load_truth_file(REPO / "examples" / "truth" / "all_effects.yaml")
    adv = [e for e in spec.effects if e.name == "wake_advection"][0]
    assert adv.full_params()["wind_x_mps"] == spec.wind_mps[0] == 0.5  # wind passed on as default
    with pytest.raises(UserError, match=r"effects\[0\].name: unknown effect 'magic'"):
        truth_from_dict({"effects": [{"name": "magic"}]}, source="t.yaml")
    with pytest.raises(UserError, match=r"effects\[0\].params.gain: unknown parameter of ground_effect"):
        truth_from_dict({"effects": [{"name": "ground_effect", "params": {"gain": 1}}]}, source="t.yaml")
    with pytest.raises(UserError, match="wind_mps: expected"):
        truth_from_dict({"wind_mps": [1, 2]}, source="t.yaml")
    with pytest.raises(UserError, match="unknown key 'efects'"):
        truth_from_dict({"efects": []}, source="t.yaml")
    (tmp_path / "bad.yaml").write_text("effects: [\n")
    with pytest.raises(UserError, match="not valid YAML"):
        load_truth_file(tmp_path / "bad.yaml")


def test_logs_have_neural_swarm_layout_and_manifest_loads(tmp_path):
    plan = swap_plan(n_swaps=1, swap_s=2.0, hold_s=0.5)
    res = simulate_plan(plan, settle_s=0.2)
    write_flight_logs(res, tmp_path, flight_name="swap_00", split="train")
    manifest = write_flight_logs(
        simulate_plan(plan, seed=1, settle_s=0.2), tmp_path, flight_name="swap_01", split="test"
    )
    real = sorted((SHARED / "data" / "neural-swarm" / "swap_sl").glob("*.csv.gz"))
    with gzip.open(tmp_path / "swap_00" / "top.csv.gz", "rt") as fh:
        header = fh.readline().strip()
    if real:
        with gzip.open(real[0], "rt") as fh:
            assert header == fh.readline().strip() == NEURAL_SWARM_HEADER
    else:  # pragma: no cover
        pytest.skip("../shared/data/neural-swarm not present: header compared to the constant only")
    table = np.loadtxt(tmp_path / "swap_00" / "top.csv.gz", delimiter=",", skiprows=1)
    assert table.shape[1] == 30
    np.testing.assert_allclose(np.diff(table[:, 0]), 10_000)  # microseconds, 100 Hz
    rec = res.records["top"]
    np.testing.assert_allclose(table[:, 1:4], rec.position_m, atol=0.005)
    np.testing.assert_allclose(table[:, 14:18], rec.motor_thrust_N)
    hover = table[:, 0] < 0.4e6
    np.testing.assert_allclose(table[hover, 9].mean(), 9.81, atol=0.05)  # az ~ +g in hover
    # the identification side reads it
    from proxplan.identify import load_manifest, read_log

    man = load_manifest(manifest)
    assert [f.name for f in man.flights] == ["swap_00", "swap_01"]
    assert {f.split for f in man.flights} == {"train", "test"}
    log = read_log(man.flights[0].vehicles[0].log)
    np.testing.assert_allclose(log.t_s, rec.t_s, atol=1e-9)
    # rewriting a flight replaces its entry; the truth stays out of the manifest
    write_flight_logs(res, tmp_path, flight_name="swap_00", split="train")
    assert len(load_manifest(manifest).flights) == 2
    assert "truth" not in manifest.read_text()
    assert (tmp_path / "swap_00" / "truth.yaml").exists()
    with pytest.raises(UserError, match="split"):
        write_flight_logs(res, tmp_path, flight_name="x", split="validation")


def test_simulate_cli_json_png_logs_and_user_errors(tmp_path, capsys):
    from proxplan.cli import main

    plan_path = _write_plan(tmp_path, hover_stack_plan(separation_m=1.0, duration_s=1.0))
    out = tmp_path / "sim"
    rc = main(
        [
            "simulate",
            str(plan_path.parent),
            "--out",
            str(out),
            "--json",
            "--log",
            "--settle",
            "0.5",
            "--truth",
            str(REPO / "examples" / "truth" / "strong_wake.yaml"),
        ]
    )
    assert rc == 0
    summary = json.loads(capsys.readouterr().out)
    assert set(summary["vehicles"]) == {"top", "bottom"}
    b = summary["vehicles"]["bottom"]
    assert b["max_altitude_error_m"] > 0.01 and b["max_authority_usage"] > 0.0
    assert summary["vehicles"]["top"]["max_authority_usage"] < 0.5 * b["max_authority_usage"]  # bias only
    assert {e["name"] for e in summary["truth"]["effects"]} == {"near_field", "thrust_quadratic", "thrust_bias"}
    assert (out / "tracking_error.png").stat().st_size > 10_000
    assert (out / "manifest.yaml").exists() and (out / "summary.json").exists()
    assert main(["simulate", str(tmp_path / "missing"), "--out", str(out)]) == 2
    assert "plan not found" in capsys.readouterr().err
    assert main(["simulate", str(plan_path), "--out", str(out), "--physics-dt", "0.002", "--log-dt", "0.003"]) == 2
    assert "multiple" in capsys.readouterr().err
    assert main(["simulate", str(plan_path), "--out", str(out), "--integral-rate", "-1"]) == 2
    assert "--integral-rate: expected a number >= 0" in capsys.readouterr().err


def test_planner_plan_result_is_accepted_like_a_path(tmp_path):
    plan_io = pytest.importorskip("proxplan.planfile.plan", reason="planner not available")
    path = _write_plan(tmp_path, hover_stack_plan(separation_m=1.0, duration_s=1.0))
    try:
        result = plan_io.read_plan(path)
    except Exception as err:  # pragma: no cover - the planner's reader wants extra keys
        pytest.skip(f"proxplan.planfile.plan.read_plan rejects a minimal plan.json: {err}")
    a = simulate_plan(result, imu_noise=False, settle_s=0.2)
    b = simulate_plan(path, imu_noise=False, settle_s=0.2)
    for name in a.records:
        np.testing.assert_array_equal(a.records[name].position_m, b.records[name].position_m)


def test_truth_wind_pushes_a_hovering_vehicle_by_rotorpy_rotor_drag():
    from proxplan.flightsim import single_hover_plan
    from proxplan.flightsim.vehicle_params import quad_params
    from proxplan.physics import BUILTIN_VEHICLES

    spec = truth_from_dict({"wind_mps": [2.0, 0.0, 0.0]})
    res = simulate_plan(
        single_hover_plan(type_name="crazyflie-2.1", duration_s=4.0), truth=spec, imu_noise=False, controller="rotorpy"
    )  # RotorPy's PD law: a steady drift F / (m kp)
    rec = res.records["solo"]
    veh = BUILTIN_VEHICLES["crazyflie-2.1"]
    p = quad_params(veh)
    omega = np.sqrt(veh.hover_thrust_per_rotor_N / p["k_eta"])
    drag_x = 4 * omega * p["k_d"] * 2.0  # RotorPy H force, N, along the wind
    drift = (rec.position_m - rec.ref_position_m)[rec.t_s > 3.5].mean(axis=0)
    np.testing.assert_allclose(drift[0], drag_x / (veh.mass_kg * 6.5), rtol=0.05)  # kp_x = 6.5 1/s^2
    assert np.all(rec.applied_force_N == 0.0)  # no downwash: the wind acts through RotorPy only


def test_simulate_cli_with_custom_vehicle_types(tmp_path, capsys):
    from proxplan.cli import main

    """A plan carries its custom types; ``--vehicles`` flies other parameters than planned; logs of
    custom types come with the vehicles file identification needs."""
    import dataclasses

    import yaml

    from proxplan.physics import load_vehicle_file

    vfile = tmp_path / "vehicles.yaml"
    vfile.write_text("vehicles:\n  heavy-cf: {base: crazyflie-2.1, mass_kg: 0.040}\n")
    heavy = load_vehicle_file(vfile)["heavy-cf"]
    plan = hover_stack_plan(separation_m=1.0, duration_s=1.0)
    bottom = plan.vehicles["bottom"]
    plan.vehicles["bottom"] = dataclasses.replace(bottom, type_name="heavy-cf", vehicle=heavy)
    write_plan(plan, tmp_path / "plan")
    path = tmp_path / "plan" / "plan.json"
    out = tmp_path / "sim"
    assert main(["simulate", str(path), "--out", str(out), "--json", "--log", "--settle", "0.2"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["vehicles"]["bottom"]["type"] == "heavy-cf"
    man_path = out / "manifest.yaml"
    doc = yaml.safe_load(man_path.read_text())
    flown = load_vehicle_file(man_path.parent / doc["vehicles_file"])
    assert flown["heavy-cf"] == heavy
    lighter = tmp_path / "lighter.yaml"
    lighter.write_text("vehicles:\n  heavy-cf: {base: crazyflie-2.1, mass_kg: 0.030}\n")
    out2 = tmp_path / "sim2"
    assert (
        main(["simulate", str(path), "--out", str(out2), "--vehicles", str(lighter), "--log", "--settle", "0.2"]) == 0
    )
    capsys.readouterr()
    doc2 = yaml.safe_load((out2 / "manifest.yaml").read_text())
    assert (out2 / doc2["vehicles_file"]).resolve() == lighter.resolve()


def test_commanded_thrust_logs_differ_from_actual_only_through_the_motor_lag(tmp_path):
    plan = swap_plan(n_swaps=1, swap_s=1.5, hold_s=0.5)
    # the plan itself: its settle is a hover (the drag lead's settle tail keeps the set-point creeping)
    res = simulate_plan(plan, imu_noise=False, settle_s=1.5, drag_compensation=False)
    write_flight_logs(res, tmp_path / "a", flight_name="f", logged_thrust="actual")
    write_flight_logs(res, tmp_path / "c", flight_name="f", logged_thrust="commanded")
    act = np.loadtxt(tmp_path / "a" / "f" / "bottom.csv.gz", delimiter=",", skiprows=1)[:, 14:18]
    cmd = np.loadtxt(tmp_path / "c" / "f" / "bottom.csv.gz", delimiter=",", skiprows=1)[:, 14:18]
    assert np.abs(act - cmd).max() > 1e-3 * np.abs(act).max()  # differ while manoeuvring
    np.testing.assert_allclose(act[-20:], cmd[-20:], rtol=2e-3)  # agree once settled
    with pytest.raises(UserError, match="logged_thrust"):
        write_flight_logs(res, tmp_path / "x", flight_name="f", logged_thrust="pwm")


def test_in_memory_vehicle_logs_equal_the_written_ones(tmp_path):
    from proxplan.flightsim import vehicle_logs
    from proxplan.identify import read_log

    res = simulate_plan(hover_stack_plan(duration_s=1.0), settle_s=0.2)
    write_flight_logs(res, tmp_path, flight_name="f")
    mem = vehicle_logs(res)
    for name in res.records:
        disk = read_log(tmp_path / "f" / f"{name}.csv.gz")
        np.testing.assert_allclose(mem[name].t_s, disk.t_s, atol=1e-9)
        for key in ("position_m", "velocity_mps", "accel_mps2", "quat_xyzw", "motor_thrust_N", "gyro_radps"):
            np.testing.assert_allclose(getattr(mem[name], key), getattr(disk, key), rtol=1e-8, atol=1e-12)
