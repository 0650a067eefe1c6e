"""`proxplan costmap`: outputs, JSON, custom vehicles, user errors."""

from __future__ import annotations

import json

import numpy as np
import pytest

from proxplan.cli import main


def _run(argv, capsys):
    code = main(argv)
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_costmap_writes_npz_png_and_one_json_object(tmp_path, capsys):
    out = tmp_path / "maps" / "sl.npz"
    code, stdout, _ = _run(
        ["costmap", "--source", "small-quad", "--target", "large-quad", "--out", str(out),
         "--levels", "0.02", "0.05", "0.3", "--default-level", "0.05", "--json"], capsys)  # fmt: skip
    assert code == 0
    doc = json.loads(stdout)  # exactly one JSON object
    assert doc["source"] == "small-quad" and doc["target"] == "large-quad"
    assert doc["levels"] == [0.02, 0.05, 0.3] and doc["default_level"] == 0.05
    assert len(doc["dz_m"]) == len(doc["r_cut_m"])
    with np.load(out) as npz:
        assert npz["dz_m"].shape == npz["r_cut_m"].shape
        assert npz["r_cut_levels_m"].shape == (3, npz["dz_m"].size)
        assert np.allclose(npz["r_cut_m"], npz["r_cut_levels_m"][1])
        assert npz["table_force_z_N"].ndim == 3
        assert json.loads(str(npz["metadata_json"]))["param_hash"] == doc["param_hash"]
    png = out.with_suffix(".png")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not list(out.parent.glob(".*"))  # no temp files left behind


def test_costmap_custom_vehicle_file_and_rule(tmp_path, capsys):
    vehicles = tmp_path / "v.yaml"
    vehicles.write_text("vehicles:\n  heavy-small:\n    base: small-quad\n    mass_kg: 0.2\n    max_thrust_N: 5.0\n")
    out = tmp_path / "custom.npz"
    code, stdout, _ = _run(
        ["costmap", "--vehicle-file", str(vehicles), "--source", "heavy-small", "--target", "crazyflie-2.1",
         "--out", str(out), "--invalid-rule", "forbid", "--no-plot", "--json"], capsys)  # fmt: skip
    assert code == 0
    doc = json.loads(stdout)
    assert doc["invalid_rule"] == "forbid" and doc["plot"] is None
    assert not out.with_suffix(".png").exists()
    from proxplan.costmaps import load_pair_maps

    maps = load_pair_maps(out)
    assert maps.metadata["source"]["mass_kg"] == 0.2
    invalid = maps.cutoff.dz_m[(maps.cutoff.dz_m > 0) & ~maps.cutoff.valid]
    assert np.ptp(maps.cutoff.r_cut_m(invalid)) == 0.0 and maps.cutoff.r_cut_m(invalid)[0] > 0


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--source", "nope", "--target", "large-quad", "--out", "x.npz"], "unknown vehicle type 'nope'"),
        (["--source", "small-quad", "--target", "large-quad", "--out", "x.png"], "--out"),
        (["--source", "small-quad", "--target", "large-quad"], "missing --out"),
        (["--source", "small-quad", "--target", "large-quad", "--out", "x.npz", "--levels", "abc"], "--levels"),
        (["--source", "small-quad", "--target", "large-quad", "--out", "x.npz", "--levels", "0.001"], "[0.01, 10]"),
        (["--all"], "--out-dir"),
        (["--all", "--out-dir", "d", "--source", "small-quad"], "--all"),
    ],
)
def test_user_errors_are_one_line_exit_2(argv, message, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, stdout, stderr = _run(["costmap", *argv], capsys)
    assert code == 2
    assert stdout == ""
    assert message in stderr
    assert stderr.count("\n") == 1 and "Traceback" not in stderr
    assert not list(tmp_path.iterdir())  # nothing half-written


def test_help(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["costmap", "--help"])
    assert exc.value.code == 0
    assert "--invalid-rule" in capsys.readouterr().out


def test_all_pairs_with_custom_vehicles(tmp_path, capsys, monkeypatch):
    from proxplan import physics

    # keep it fast: one built-in type plus one custom type -> 4 ordered pairs
    monkeypatch.setattr(physics, "BUILTIN_VEHICLES", {"crazyflie-2.1": physics.BUILTIN_VEHICLES["crazyflie-2.1"]})
    vehicles = tmp_path / "v.yaml"
    vehicles.write_text("vehicles:\n  cf-heavy:\n    base: crazyflie-2.1\n    mass_kg: 0.036\n")
    code, stdout, stderr = _run(
        [
            "costmap",
            "--all",
            "--out-dir",
            str(tmp_path / "maps"),
            "--vehicle-file",
            str(vehicles),
            "--no-plot",
            "--json",
        ],
        capsys,
    )
    assert code == 0
    doc = json.loads(stdout)
    pairs = {(m["source"], m["target"]) for m in doc["maps"]}
    assert pairs == {(s, t) for s in ("crazyflie-2.1", "cf-heavy") for t in ("crazyflie-2.1", "cf-heavy")}
    assert sorted(p.name for p in (tmp_path / "maps").glob("*.npz")) == sorted(f"{s}__{t}.npz" for s, t in pairs)
    assert "costmap" in stderr  # the progress bar goes to stderr
