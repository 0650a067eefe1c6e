"""In-process tests of the review app (web/): scene nodes, time slider, layers, plots, re-plan, export."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import viser

from proxplan.physics import (
    BUILTIN_VEHICLES,
    VALIDITY_FACTOR_L,
    authority_usage,
    disturbance_wrench,
    downwash_speed_mps,
)
from proxplan.web import (
    ReviewApp,
    layers,
    load_plan_file,
    plots,
    prepare,
)
from proxplan.web.demo import DEMO_SPEC, write_demo_plan
from proxplan.web.wrench_series import WrenchSeries


@pytest.fixture(scope="module")
def plan_path(tmp_path_factory) -> Path:
    return write_demo_plan(tmp_path_factory.mktemp("demo"))


@pytest.fixture(scope="module")
def app(plan_path):
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    review = ReviewApp(server, plan_path)
    assert review.load()
    review.wait_idle(60.0)
    assert review.loaded is not None, review.status.content
    yield review
    review.stop()
    server.stop()


def _nodes(app) -> set[str]:
    return set(app.server.scene._handle_from_node_name)


def _plan_positions(plan_path: Path, t_s: float) -> dict[str, np.ndarray]:
    """Independent reading of plan.json: linear interpolation of position_m at t_s."""
    doc = json.loads(plan_path.read_text())
    out = {}
    for name, v in doc["vehicles"].items():
        t = np.asarray(v["t_s"])
        p = np.asarray(v["position_m"])
        out[name] = np.array([np.interp(t_s, t, p[:, k]) for k in range(3)])
    return out


def test_scene_holds_one_node_per_vehicle_trajectory_and_obstacle(app):
    nodes = _nodes(app)
    names = set(DEMO_SPEC["vehicles"])
    assert {f"/vehicles/{n}" for n in names} <= nodes
    assert {f"/trajectories/{n}" for n in names} <= nodes
    n_obst = len(DEMO_SPEC["obstacles"])
    assert {f"/obstacles/{k}" for k in range(n_obst)} <= nodes
    assert f"/obstacles/{n_obst}" not in nodes
    assert {"/ground", "/workspace"} <= nodes
    vehicle_nodes = {n for n in nodes if n.count("/") == 2 and n.startswith("/vehicles/")}
    assert vehicle_nodes == {f"/vehicles/{n}" for n in names}


@pytest.mark.parametrize("t_s", [0.0, 2.35, 5.0, 8.0])
def test_time_slider_moves_vehicles_to_plan_positions(app, plan_path, t_s):
    app.time_slider.value = t_s  # the GUI path: slider update callback
    expected = _plan_positions(plan_path, t_s)
    for name, frame in app._handles.vehicles.items():
        np.testing.assert_allclose(frame.position, expected[name], atol=1e-6)
    moving = np.array(app._handles.vehicles["shuttle"].position)
    app.time_slider.value = 0.0 if t_s > 0 else 4.0
    assert not np.allclose(app._handles.vehicles["shuttle"].position, moving)


def test_layers_toggle_and_follow_source(app):
    app.source.value = "carrier"
    assert "/vehicles/carrier/downwash/cutoff" in _nodes(app)
    assert not any(n.startswith("/vehicles/shuttle/downwash") for n in _nodes(app))
    app.show_iso.value = False
    iso = [h for h in app._layer_handles if "/iso_" in h.name]
    assert iso and not any(h.visible for h in iso)
    app.show_iso.value = True
    assert all(h.visible for h in iso)
    app.show_traj.value = False
    assert not any(h.visible for h in app._handles.trajectories.values())
    app.show_traj.value = True


def test_iso_speed_profile_lies_on_the_model_speed():
    src = BUILTIN_VEHICLES["large-quad"]
    for prof, level in zip(layers.iso_speed_profiles(src, depth_m=3.0), layers.DEFAULT_ISO_LEVELS_MPS):
        inside = prof.r_m > 0.0
        assert inside.sum() > 5
        v = downwash_speed_mps(src, prof.dz_m[inside], prof.r_m[inside] ** 2)
        np.testing.assert_allclose(v, level, rtol=0.02)


def test_cutoff_profile_separates_usage_above_and_below_the_level():
    src, tgt = BUILTIN_VEHICLES["large-quad"], BUILTIN_VEHICLES["small-quad"]
    level = 0.1
    prof = layers.cutoff_profile(src, tgt, depth_m=2.0, level=level)
    valid = prof.dz_m > VALIDITY_FACTOR_L * src.size_m  # the invalid zone holds a conservative floor
    k = np.nonzero(valid & (prof.r_m > 0.05))[0]
    assert k.size > 0, "a large quad must disturb a small one noticeably near its axis"
    dz, r = prof.dz_m[k], prof.r_m[k]

    def worst_usage(radius):  # max over azimuth, as the cutoff map defines it
        out = np.zeros_like(radius)
        for az in np.radians([0.0, 15.0, 30.0, 45.0]):
            offsets = np.column_stack([radius * np.cos(az), radius * np.sin(az), -dz])
            w = disturbance_wrench(src, tgt, offsets)
            out = np.maximum(out, authority_usage(tgt, w.force_N, w.torque_Nm))
        return out

    assert np.all(worst_usage(r * 1.15 + 0.02) < level)  # beyond r_cut: below the level everywhere
    clear_peak = worst_usage(np.zeros_like(r)) > 1.2 * level  # near the surface's tip the map is coarse
    assert clear_peak.sum() > 5
    assert np.all(worst_usage(0.5 * r)[clear_peak] >= level)  # well inside: above it


def test_plot_marker_column_follows_time():
    t = np.linspace(0.0, 10.0, 50)
    series = WrenchSeries(t, np.zeros((50, 3)), np.zeros((50, 3)), np.linspace(0, 0.3, 50))
    img = plots.render_series(series, name="x", limit=0.4)
    cols = [img.column_of(v) for v in (0.0, 5.0, 10.0)]
    assert cols[0] < cols[1] < cols[2]
    assert abs(cols[1] - 0.5 * (cols[0] + cols[2])) <= 1
    marked = img.with_marker(5.0)
    red = (marked[:, :, 0] > 200) & (marked[:, :, 1] < 30) & (marked[:, :, 2] < 30)
    assert red[:, cols[1]].sum() > 0.5 * (img.y_px_range[1] - img.y_px_range[0])
    assert red[:, cols[0] + 20].sum() < 5


def test_bad_plan_file_keeps_app_alive_with_message(app, tmp_path):
    bad = tmp_path / "plan.json"
    bad.write_text("{not json")
    before = app.loaded
    assert app.load(bad)
    app.wait_idle(30.0)
    assert app.loaded is before  # the previous plan stays
    assert "Error" in app.status.content and "not valid JSON" in app.status.content
    app.load(app.loaded.data.source_path)  # back to the good plan for the other tests
    app.wait_idle(30.0)


def test_replan_failure_keeps_old_plan_and_success_shows_new(app, plan_path):
    before = app.loaded
    app.edit_vehicle.value = "other"
    assert app._gizmo is not None
    np.testing.assert_allclose(app._gizmo.position, DEMO_SPEC["vehicles"]["other"]["goal"])
    app._gizmo.position = (2.0, 1.0, 1.5)
    edited = app.edited_scenario()
    np.testing.assert_allclose(edited.vehicles["other"].goal_m, (2.0, 1.0, 1.5))

    def failing(scenario, *, progress):
        progress("sampling", 0.3)
        raise RuntimeError("planner exploded")

    assert app._jobs.submit(edited, plan_fn=failing)
    app.wait_idle(30.0)
    assert app.loaded is before
    assert "planner exploded" in app.status.content

    def shifted(scenario, *, progress):  # a "planner" that moves every trajectory up by 0.25 m
        data = load_plan_file(plan_path)
        plan = data.plan
        import dataclasses

        for name, tr in plan.vehicles.items():
            plan.vehicles[name] = dataclasses.replace(tr, position_m=tr.position_m + [0.0, 0.0, 0.25])
        from proxplan.web import review_from_plan_result

        return prepare(review_from_plan_result(plan, scenario, source_path=plan_path))

    assert app._jobs.submit(edited, plan_fn=shifted)
    app.wait_idle(30.0)
    assert app.loaded is not before
    app.time_slider.value = 3.0
    expected = _plan_positions(plan_path, app.t_s)
    np.testing.assert_allclose(app._handles.vehicles["other"].position, expected["other"] + [0, 0, 0.25], atol=1e-6)
    app.edit_vehicle.value = "(none)"
    app.load(plan_path)  # back to the file's plan for the other tests
    app.wait_idle(30.0)


def test_export_writes_self_contained_recording(app, tmp_path):
    out = app.export(tmp_path / "rec", frame_dt_s=0.5)
    names = {p.name for p in out.iterdir()}
    assert names == {"recording.viser", "index.html", "README.txt"}
    assert (out / "recording.viser").stat().st_size > 1000
    assert "playbackPath=recording.viser" in (out / "README.txt").read_text()
    # the live scene is back at the time it showed before the export
    t = app.t_s
    np.testing.assert_allclose(
        app._handles.vehicles["shuttle"].position, _plan_positions(app.loaded.data.source_path, t)["shuttle"], atol=1e-6
    )


def test_cli_missing_file_is_one_line_user_error(tmp_path):
    proc = subprocess.run(
        [sys.executable, "-m", "proxplan.cli", "view", str(tmp_path / "nope.yaml")],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 2
    assert proc.stderr.strip().count("\n") == 0 and "no such file" in proc.stderr


def test_cli_export_prints_one_json_object(plan_path, tmp_path):
    proc = subprocess.run(
        [sys.executable, "-m", "proxplan.cli", "view", str(plan_path), "--export", str(tmp_path / "rec"), "--json"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    doc = json.loads(proc.stdout)
    assert Path(doc["export_dir"], "recording.viser").exists()


def test_play_advances_time(app):
    app.time_slider.value = 0.0
    app.speed.value = 2.0
    app.play.value = True
    try:
        import time

        time.sleep(0.6)
    finally:
        app.play.value = False
    assert 0.4 < app.t_s < 3.0  # about 0.6 s x 2 of plan time (thread timing is loose)
    np.testing.assert_allclose(
        app._handles.vehicles["shuttle"].position,
        _plan_positions(app.loaded.data.source_path, app.t_s)["shuttle"],
        atol=1e-6,
    )


SHIPPED_SCENARIO = Path(__file__).resolve().parents[2] / "scenarios" / "battery_swap.yaml"


@pytest.mark.skipif(not SHIPPED_SCENARIO.exists(), reason="scenarios/battery_swap.yaml not shipped")
def test_scenario_is_planned_then_dock_offset_edit_replans_in_background():
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    stages: list[str] = []
    review = ReviewApp(server, SHIPPED_SCENARIO, terminal_progress=lambda s, f: stages.append(s))
    try:
        review.load()
        review.wait_idle(120.0)
        assert review.loaded is not None, review.status.content
        assert stages, "planning progress must be reported"
        first = review.loaded
        docked = [n for n, v in first.data.vehicles.items() if v.dock_with]
        assert docked
        name = docked[0]
        partner = first.data.vehicles[name].dock_with
        review.edit_vehicle.value = name
        origin = first.data.vehicles[partner].position_m[-1]
        new_offset = first.data.vehicles[name].dock_offset_m + [0.0, 0.0, 0.2]
        review._gizmo.position = tuple(origin + new_offset)
        assert review.replan()
        assert review._jobs.busy or review.loaded is not first  # runs in the background
        review.wait_idle(120.0)
        assert review.loaded is not first, review.status.content
        new = review.loaded.data
        np.testing.assert_allclose(new.vehicles[name].dock_offset_m, new_offset, atol=1e-9)
        end_gap = new.vehicles[name].position_m[-1] - new.vehicles[partner].position_m[-1]
        np.testing.assert_allclose(end_gap, new_offset, atol=0.05)
    finally:
        review.stop()
        server.stop()


def test_plan_without_scenario_shows_trajectories_and_says_why_editing_is_off(plan_path, tmp_path):
    doc = json.loads(plan_path.read_text())
    doc["scenario_spec"] = None
    doc["scenario_file"] = None
    bare = tmp_path / "plan.json"
    bare.write_text(json.dumps(doc))
    server = viser.ViserServer(host="127.0.0.1", port=0, verbose=False)
    review = ReviewApp(server, bare)
    try:
        review.load()
        review.wait_idle(60.0)
        assert review.loaded is not None, review.status.content
        assert review.loaded.data.scenario is None
        assert "no scenario" in review.status.content or "scenario not loaded" in review.status.content
        assert set(review._handles.trajectories) == set(doc["vehicles"])
        assert review.edit_vehicle.options == ("(none)",)
        assert review.replan() is False
        review.time_slider.value = 6.0
        np.testing.assert_allclose(
            review._handles.vehicles["other"].position, _plan_positions(bare, 6.0)["other"], atol=1e-6
        )
    finally:
        review.stop()
        server.stop()


def test_cli_bad_host_is_one_line_user_error(plan_path):
    proc = subprocess.run(
        [sys.executable, "-m", "proxplan.cli", "view", str(plan_path), "--host", "999.1.1.1"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 2
    assert proc.stderr.strip().count("\n") == 0 and "--host 999.1.1.1" in proc.stderr
