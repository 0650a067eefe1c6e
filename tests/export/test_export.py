"""Export: the Crazyflie polynomials reproduce every shipped plan's drag-compensated reference within
1 cm, are C2 at every joint, use <= 31 pieces, are predicted to fly the plan and pass the verifier (a
corrupted export does not); without the compensation the vehicles are predicted to lag the plan;
a plan too wiggly for 31 pieces gives the clear error (or several uploads with --split-time); the
set-point CSVs carry the predicted downwash and the drag feed-forward."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from proxplan.export import (
    SPLIT_PART_PIECES,
    DoesNotFitError,
    export_crazyflie,
    export_setpoints,
    export_vehicle,
    vehicle_limits,
)
from proxplan.physics import BUILTIN_VEHICLES, KinematicLimits
from proxplan.planfile import (
    CRAZYFLIE_MAX_PIECES,
    EXPORT_MANIFEST,
    Plan,
    PolynomialTrajectory,
    VehicleTrajectory,
    read_export,
    read_plan,
    read_uav_csv,
    write_plan,
)
from proxplan.planfile.reference import compensated_reference
from proxplan.verify import scenario_of_plan, verify_plan
from tests.conftest import SCENARIOS, run_proxplan

SHIPPED = sorted(p.stem for p in SCENARIOS.glob("*.yaml"))
PROMISE_M = 0.01  # the export's promise; the default fit tolerance is half of it
TIGHT_M = 0.001  # tolerance of the wiggly plan tests, m


@pytest.fixture(scope="module")
def exported(tmp_path_factory, shipped_plans: dict[str, Path]) -> dict[str, tuple[Plan, Path]]:
    """Every shipped scenario planned (sampling, seed 0, fresh process) and exported. The plans are the
    session's ``shipped_plans`` (tests/conftest.py: the same command, once per session; the planner's
    tests/planner/test_scenarios_shipped.py verifies the same plans)."""
    out = {}
    for name in SHIPPED:
        folder = tmp_path_factory.mktemp(name)
        plan = read_plan(shipped_plans[name])
        export_crazyflie(plan, scenario_of_plan(plan), folder / "cf")
        out[name] = (plan, folder / "cf")
    return out


def _uploads(folder: Path, vehicle: str) -> list[PolynomialTrajectory]:
    manifest = json.loads((folder / EXPORT_MANIFEST).read_text())
    files = manifest["vehicles"][vehicle]["files"]
    assert all(vehicle in f["file"] for f in files)
    return [read_uav_csv(folder / f["file"], start_time_s=f["start_time_s"]) for f in files]


@pytest.mark.parametrize("scenario", SHIPPED)
def test_export_reproduces_the_compensated_reference_c2_and_fits(exported, scenario):
    plan, folder = exported[scenario]
    for name, tr in plan.vehicles.items():
        (traj,) = _uploads(folder, name)
        ref = compensated_reference(tr).trajectory  # plan + drag lead, one step early, with its settle tail
        assert traj.n_pieces <= CRAZYFLIE_MAX_PIECES
        assert traj.start_time_s == pytest.approx(ref.t_s[0]) and traj.end_time_s == pytest.approx(ref.t_s[-1])
        assert traj.start_time_s == pytest.approx(tr.t_s[0] - plan.dt_s) and traj.end_time_s >= tr.t_s[-1]
        t = np.linspace(ref.t_s[0], ref.t_s[-1], 20 * ref.t_s.size + 7)  # dense, off the plan grid
        dev = np.linalg.norm(traj.evaluate(t)[:, :3] - ref.position_at(t), axis=1)
        assert dev.max() <= PROMISE_M, (name, dev.max())
        assert np.all(traj.coef[:, 3, :] == 0.0)  # yaw 0: plans carry no yaw
        for j in range(traj.n_pieces - 1):  # C2: left piece at its end == right piece at its start
            end = traj.joints_s[j + 1]
            for d, tol in ((0, 1e-6), (1, 1e-5), (2, 1e-4)):
                left = np.polynomial.polynomial.polyval(
                    traj.durations_s[j], np.polynomial.polynomial.polyder(traj.coef[j, :3].T, d)
                )
                right = np.polynomial.polynomial.polyval(
                    0.0, np.polynomial.polynomial.polyder(traj.coef[j + 1, :3].T, d)
                )
                assert np.abs(left - right).max() <= tol, (name, j, d, end)
        start = tr.sample(tr.t_s[0])
        for d in range(3):  # starts at rest where the plan starts (its lead is zero before it moves)
            assert np.allclose(traj.evaluate(traj.start_time_s, d)[0, :3], start[d][0], atol=1e-6)
        # the vehicle, lagging its upload, is predicted to fly the plan
        flown = read_export(folder).vehicles[name]
        assert np.linalg.norm(flown.position_m - tr.position_at(flown.t_s), axis=1).max() <= PROMISE_M


@pytest.mark.parametrize("scenario", SHIPPED)
def test_verify_passes_on_exported_folder(exported, scenario):
    plan, folder = exported[scenario]
    flown = read_export(folder)
    assert set(flown.vehicles) == set(plan.vehicles)
    assert verify_plan(flown, scenario_of_plan(flown)) == []


def test_verify_cli_on_export_and_on_corrupted_copy(exported, tmp_path):
    _, folder = exported["battery_swap"]
    ok = run_proxplan("verify", folder, "--json")
    assert ok.returncode == 0, ok.stderr
    assert json.loads(ok.stdout)["passed"] and json.loads(ok.stdout)["exported"]
    bad = tmp_path / "bad"
    bad.mkdir()
    for f in folder.iterdir():
        (bad / f.name).write_text(f.read_text())
    csv = bad / "shuttle.csv"
    rows = csv.read_text().splitlines()
    cells = rows[2].split(",")
    cells[17] = repr(float(cells[17]) + 0.3)  # z^0 of the second piece: a 30 cm jump at a joint
    rows[2] = ",".join(cells)
    csv.write_text("\n".join(rows) + "\n")
    res = run_proxplan("verify", bad, "--json")
    assert res.returncode == 1, res.stderr
    assert json.loads(res.stdout)["violations"]


def _wiggly_plan(duration_s: float = 60.0, ramp_s: float = 1.0) -> Plan:
    """One crazyflie (limits 1.5 m/s, 3 m/s^2, 15 m/s^3 stated here) swinging +-0.1 m in x at
    5 rad/s for ``duration_s`` (within those limits; the swing fades in and out over ``ramp_s``, so
    it starts and ends at rest as plans do): more than 31 pieces at :data:`TIGHT_M`."""
    dt = 0.02
    t = np.arange(int(round(duration_s / dt)) + 1) * dt
    w = 5.0
    s = np.clip(np.minimum(t, duration_s - t) / ramp_s, 0.0, 1.0)
    sign = np.where(t < duration_s / 2, 1.0, -1.0) * (s < 1.0) / ramp_s  # ds/dt on the ramps
    env = 10 * s**3 - 15 * s**4 + 6 * s**5
    d_env = (30 * s**2 - 60 * s**3 + 30 * s**4) * sign
    dd_env = (60 * s - 180 * s**2 + 120 * s**3) * sign**2
    sin, cos = np.sin(w * t), np.cos(w * t)
    p = np.zeros((t.size, 3))
    v, a = np.zeros_like(p), np.zeros_like(p)
    p[:, 0] = 0.1 * env * sin
    v[:, 0] = 0.1 * (d_env * sin + env * w * cos)
    a[:, 0] = 0.1 * (dd_env * sin + 2 * d_env * w * cos - env * w**2 * sin)
    p[:, 2] = 1.0
    vehicle = replace(BUILTIN_VEHICLES["crazyflie-2.1"], kinematics=KinematicLimits(1.5, 3.0, 15.0))
    tr = VehicleTrajectory("wiggler", "crazyflie-2.1", vehicle, t, p, v, a)
    return Plan("wiggly", dt, {"wiggler": tr}, method="test")


def test_too_wiggly_plan_gives_clear_error_and_splits_on_request():
    plan = _wiggly_plan()
    tr, limits = plan.vehicles["wiggler"], vehicle_limits(plan, None, "wiggler")
    with pytest.raises(DoesNotFitError) as err:
        export_vehicle(tr, limits=limits, tolerance_m=TIGHT_M)
    message = str(err.value)
    assert "wiggler" in message and "31" in message and "mm" in message and "--split-time" in message
    assert err.value.pieces > CRAZYFLIE_MAX_PIECES
    assert err.value.deviation_m > TIGHT_M or err.value.kinematic_ratio > 1.0
    parts = export_vehicle(tr, limits=limits, tolerance_m=TIGHT_M, split_time=True)
    assert len(parts) >= 3
    t = np.linspace(0.0, tr.t_s[-1], 30001)
    for i, part in enumerate(parts):
        traj = part.trajectory
        assert traj.n_pieces <= SPLIT_PART_PIECES
        inside = (t >= traj.start_time_s) & (t <= traj.end_time_s)
        dev = np.linalg.norm(traj.evaluate(t[inside])[:, :3] - tr.position_at(t[inside]), axis=1)
        assert dev.max() <= 2 * TIGHT_M
        if i:  # consecutive uploads join C2
            prev = parts[i - 1].trajectory
            assert prev.end_time_s == pytest.approx(traj.start_time_s)
            for d in range(3):
                assert np.allclose(prev.evaluate(prev.end_time_s, d), traj.evaluate(traj.start_time_s, d), atol=1e-4)


def test_cli_does_not_fit(tmp_path):
    """The wiggly plan's upload (plan + drag lead, with its settle tail) needs more than 31 pieces:
    exit 1, one line naming the vehicle and what it fits, nothing written."""
    write_plan(_wiggly_plan(), tmp_path / "plan")
    out = tmp_path / "cf"
    tight = ("--tolerance-m", TIGHT_M)
    res = run_proxplan("export", tmp_path / "plan", "--format", "crazyflie", "--out", out, *tight, "--json")
    assert res.returncode == 1
    (line,) = res.stderr.strip().splitlines()
    assert "'wiggler'" in line and "drag lead" in line and "31" in line
    doc = json.loads(res.stdout)
    assert doc["fits"] is False and doc["vehicle"] == "wiggler" and doc["pieces"] > CRAZYFLIE_MAX_PIECES
    assert not out.exists()  # nothing written


@pytest.mark.slow
def test_cli_split_time_uploads_reread(tmp_path):
    write_plan(_wiggly_plan(), tmp_path / "plan")
    out = tmp_path / "cf"
    tight = ("--tolerance-m", TIGHT_M)
    res = run_proxplan(
        "export", tmp_path / "plan", "--format", "crazyflie", "--out", out, *tight, "--split-time", "--json"
    )
    assert res.returncode == 0, res.stderr
    files = json.loads(res.stdout)["files"]
    assert len(files) >= 3 and all(f["pieces"] <= SPLIT_PART_PIECES and f["max_deviation_m"] <= TIGHT_M for f in files)
    flown = read_export(out)
    t = flown.t_s
    dev = np.linalg.norm(
        flown.vehicles["wiggler"].position_m - _wiggly_plan().vehicles["wiggler"].position_at(t), axis=1
    )
    assert dev.max() <= PROMISE_M


def test_setpoints_carry_the_downwash(exported, tmp_path):
    plan, _ = exported["battery_swap"]
    rows, notes = export_setpoints(plan, scenario_of_plan(plan), tmp_path, rate_hz=50.0)
    assert notes and "plan.json" in notes[0]  # proxplan plan stores the feed-forward wrench
    carrier = np.loadtxt(tmp_path / rows["carrier"]["file"], delimiter=",", skiprows=1)
    shuttle = np.loadtxt(tmp_path / rows["shuttle"]["file"], delimiter=",", skiprows=1)
    header = (tmp_path / rows["carrier"]["file"]).read_text().splitlines()[0].split(",")
    assert header[:4] == ["t_s", "x_m", "y_m", "z_m"] and header[15] == "ff_fz_N"
    steps = np.diff(carrier[:, 0])  # 50 Hz from the start; the plan's end is included (a shorter last step)
    assert np.allclose(steps[:-1], 0.02, atol=1e-6) and 0.0 < steps[-1] <= 0.02 + 1e-6
    assert carrier[-1, 0] == pytest.approx(plan.makespan_s)
    assert carrier[-1, 15] < 0.0  # docked shuttle on top: its downwash pushes the carrier down
    assert np.all(shuttle[:, 13:] == 0.0) or shuttle[-1, 3] > carrier[-1, 3]  # nothing above the shuttle at the end
    assert np.allclose(shuttle[:, 1:4], plan.vehicles["shuttle"].position_at(shuttle[:, 0]), atol=1e-6)


def test_cli_bad_input(exported, tmp_path):
    plan, _ = exported["battery_swap"]
    write_plan(plan, tmp_path / "plan")
    res = run_proxplan("export", tmp_path / "plan", "--format", "px4", "--out", tmp_path / "x")
    assert res.returncode == 2 and len(res.stderr.strip().splitlines()) == 1
    blocker = tmp_path / "file"
    blocker.write_text("")
    res = run_proxplan("export", tmp_path / "plan", "--format", "csv", "--out", blocker)
    assert res.returncode == 2 and len(res.stderr.strip().splitlines()) == 1 and "--out" in res.stderr
    doc = json.loads((tmp_path / "plan" / "plan.json").read_text())
    doc["vehicles"]["shuttle"]["position_m"][3][0] = float("nan")
    (tmp_path / "nan").mkdir()
    (tmp_path / "nan" / "plan.json").write_text(json.dumps(doc))
    res = run_proxplan("export", tmp_path / "nan", "--format", "crazyflie", "--out", tmp_path / "y")
    assert res.returncode == 2 and len(res.stderr.strip().splitlines()) == 1 and "not finite" in res.stderr
    assert not (tmp_path / "x").exists() and not (tmp_path / "y").exists()


def test_cli_json_names_files_pieces_and_deviation(exported, tmp_path):
    plan, _ = exported["package_handoff"]
    write_plan(plan, tmp_path / "plan")
    out = tmp_path / "cf"
    res = run_proxplan("export", tmp_path / "plan", "--format", "crazyflie", "--out", out, "--json")
    assert res.returncode == 0, res.stderr
    doc = json.loads(res.stdout)
    assert doc["fits"] and Path(doc["manifest"]).is_file()
    assert {f["vehicle"] for f in doc["files"]} == set(plan.vehicles)
    for f in doc["files"]:
        assert f["vehicle"] in Path(f["file"]).name and Path(f["file"]).is_file()
        assert 1 <= f["pieces"] <= CRAZYFLIE_MAX_PIECES and 0.0 <= f["max_deviation_m"] <= 0.005
        assert read_uav_csv(f["file"]).n_pieces == f["pieces"]


def test_malformed_uav_csv_is_a_user_error(tmp_path):
    from proxplan.fileio import UserError

    bad = tmp_path / "bad.csv"
    bad.write_text("Duration,x^0\n1.0,2.0\n")
    with pytest.raises(UserError, match="line 2"):
        read_uav_csv(bad)
    bad.write_text("Duration," + ",".join(["0"] * 32) + "\n-1," + ",".join(["0"] * 32) + "\n")
    with pytest.raises(UserError, match="Duration"):
        read_uav_csv(bad)


def test_setpoints_use_stored_feedforward_or_recompute(exported, tmp_path):
    plan, _ = exported["battery_swap"]
    assert all(tr.has_feedforward for tr in plan.vehicles.values())  # proxplan plan stores them
    rows, notes = export_setpoints(plan, scenario_of_plan(plan), tmp_path / "stored", rate_hz=20.0)
    assert "disturbance_force_N" in notes[0]
    carrier = plan.vehicles["carrier"]
    table = np.loadtxt(tmp_path / "stored" / rows["carrier"]["file"], delimiter=",", skiprows=1)
    assert np.allclose(table[:, 0], carrier.t_s)  # 20 Hz = the plan's 0.05 s grid
    assert np.allclose(table[:, 13:16], carrier.disturbance_force_N, atol=1e-6)
    old = replace(
        plan,
        vehicles={
            n: replace(tr, disturbance_force_N=None, disturbance_torque_Nm=None) for n, tr in plan.vehicles.items()
        },
    )
    rows, notes = export_setpoints(old, scenario_of_plan(old), tmp_path / "old", rate_hz=20.0)
    assert "recomputed" in notes[0]
    recomputed = np.loadtxt(tmp_path / "old" / rows["carrier"]["file"], delimiter=",", skiprows=1)
    scale = max(1e-9, float(np.abs(carrier.disturbance_force_N).max()))
    assert np.abs(recomputed[:, 13:16] - carrier.disturbance_force_N).max() <= 1e-3 * scale + 1e-6


def test_setpoints_acceleration_carries_the_drag_term(exported, tmp_path):
    """a = the plan's acceleration + c v (documented column drag_a*), and nothing without compensation."""
    plan, _ = exported["battery_swap"]
    shuttle = plan.vehicles["shuttle"]
    rows, notes = export_setpoints(plan, scenario_of_plan(plan), tmp_path / "on", rate_hz=20.0)
    on = np.loadtxt(tmp_path / "on" / rows["shuttle"]["file"], delimiter=",", skiprows=1)
    header = (tmp_path / "on" / rows["shuttle"]["file"]).read_text().splitlines()[0].split(",")
    assert header[7:13] == ["ax_mps2", "ay_mps2", "az_mps2", "drag_ax_mps2", "drag_ay_mps2", "drag_az_mps2"]
    _, v, a = shuttle.sample(on[:, 0])
    np.testing.assert_allclose(on[:, 10:13], shuttle.vehicle.drag_rate_ps * v, atol=1e-9)
    np.testing.assert_allclose(on[:, 7:10], a + shuttle.vehicle.drag_rate_ps * v, atol=1e-9)
    assert np.linalg.norm(on[:, 10:13], axis=1).max() > 0.05  # ~0.24 1/s x the shuttle's speed
    assert any("drag" in n for n in notes)
    rows, _ = export_setpoints(plan, scenario_of_plan(plan), tmp_path / "off", rate_hz=20.0, drag_compensation=False)
    off = np.loadtxt(tmp_path / "off" / rows["shuttle"]["file"], delimiter=",", skiprows=1)
    assert np.all(off[:, 10:13] == 0.0)
    np.testing.assert_allclose(off[:, 7:10], a, atol=1e-9)


def test_without_compensation_the_upload_is_the_plan_and_the_vehicle_lags_it(exported, tmp_path):
    """--no-drag-compensation uploads the plan; its predicted flight lags the plan by the rotor drag,
    by more than the type's tube (crossing 4: ~4.5 cm), where the compensated export is predicted to
    fly the plan within a few mm."""
    plan, folder = exported["crossing_4"]
    write_plan(plan, tmp_path / "plan")
    out = tmp_path / "raw"
    res = run_proxplan(
        "export", tmp_path / "plan", "--format", "crazyflie", "--out", out, "--no-drag-compensation", "--json"
    )
    assert res.returncode == 0, res.stderr
    doc = json.loads(res.stdout)
    assert doc["drag_compensation"] is False and all(f["drag_compensation"] is None for f in doc["files"])
    lagged = read_export(out)
    flown = read_export(folder)
    for name, tr in plan.vehicles.items():
        (raw,) = _uploads(out, name)
        assert raw.start_time_s == pytest.approx(0.0) and raw.end_time_s == pytest.approx(tr.t_s[-1])
        t = np.linspace(0.0, tr.t_s[-1], 2001)
        assert np.linalg.norm(raw.evaluate(t)[:, :3] - tr.position_at(t), axis=1).max() <= PROMISE_M
        lagging = np.linalg.norm(lagged.vehicles[name].position_m - tr.position_at(lagged.t_s), axis=1).max()
        on_plan = np.linalg.norm(flown.vehicles[name].position_m - tr.position_at(flown.t_s), axis=1).max()
        assert lagging > 2 * tr.vehicle.tracking_tube_m and on_plan < 0.25 * tr.vehicle.tracking_tube_m, (name, lagging)
    manifest = json.loads((folder / EXPORT_MANIFEST).read_text())
    lead = manifest["vehicles"]["east"]["drag_compensation"]
    assert manifest["drag_compensation"] is True and lead["max_lead_m"] > 0.02 and lead["tail_s"] > 0.0
