"""``proxplan evaluate``: a saved model reproduces identify's "after" without refitting; bad input."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from proxplan.identify import synthetic_logs, write_canonical_csv
from proxplan.identify.synthetic_logs import SyntheticMotor
from proxplan.physics import BUILTIN_VEHICLES, Effect

TYPE = "crazyflie-2.1"
MOTOR = SyntheticMotor(max_thrust_N=0.11)  # weak motors (T/W 1.4): the bobbing saturates them


def _manifest(tmp: Path, *, n_train: int = 2, pwm: bool = True, score_b: bool = True) -> Path:
    """Crazyflie 'b' bobbing hard (motors saturate on up-strokes) 0.25-0.55 m below 'a', with a
    hidden thrust bias; canonical logs with PWM/Vbat (``pwm``)."""
    veh = BUILTIN_VEHICLES[TYPE]
    t = np.arange(0.0, 8.0, 0.01)
    flights = []
    for k in range(n_train + 1):
        ph = 0.7 * k
        a = np.column_stack([0.03 * np.sin(t + ph), 0 * t, 1.2 + 0 * t])
        b = np.column_stack([0.05 * np.sin(0.8 * t + ph), 0 * t,
                             0.8 + 0.1 * np.sin(0.9 * t + ph) + 0.03 * np.sin((13.0 + k) * t)])  # fmt: skip
        logs = synthetic_logs({"a": veh, "b": veh}, {"a": a, "b": b}, t, effects=(Effect("thrust_bias", {"force_z_N": 0.01}),),
                              accel_noise_mps2=0.02, seed=k, motor=MOTOR if pwm else None)  # fmt: skip
        entry: dict = {"name": f"f{k}", "split": "test" if k == n_train else "train", "vehicles": {}}
        for name, log in logs.items():
            write_canonical_csv(log, tmp / f"f{k}_{name}.csv.gz")
            entry["vehicles"][name] = {"type": TYPE, "log": f"f{k}_{name}.csv.gz"}
        if not score_b:
            entry["vehicles"]["b"]["score"] = False
        flights.append(entry)
    path = tmp / "manifest.yaml"
    path.write_text(yaml.safe_dump({"format": "canonical", "root": ".", "flights": flights}))
    return path


def test_round_trip_reproduces_identify_after(tmp_path: Path, capsys) -> None:
    from proxplan.cli import main

    manifest = _manifest(tmp_path)
    model = tmp_path / "model.yaml"
    assert main(["identify", str(manifest), "--out", str(tmp_path / "id"), "--json", "--save-model", str(model)]) == 0
    ident = json.loads(capsys.readouterr().out)
    sat = ident["measurement"]["saturation"]["b"]
    assert sat["thrust_source"] == "pwm" and sat["saturated_samples"] > 50  # the logs really saturate
    assert main(["evaluate", str(manifest), "--model", str(model), "--out", str(tmp_path / "ev"), "--json"]) == 0
    ev = json.loads(capsys.readouterr().out)
    assert ev["rmse_fz_N"] == pytest.approx(ident["after"]["rmse_fz_N"], rel=0.01)
    assert ev["n_samples"] == ident["after"]["n_samples"]
    assert ev["rmse_fz_N"] < 0.8 * ev["no_model"]["rmse_fz_N"]
    assert set(ev["per_vehicle"]) == {"a", "b"} and set(ev["flights"]) == {"f2"}
    assert ev["n_samples"] <= ev["n_rows"] and (tmp_path / "ev" / "flights.png").stat().st_size > 1000
    # issue 29: samples split by authority state (a partition), each with grams beside the ratio
    auth = ev["authority"]
    assert set(auth) == {"in_range", "at_limit", "knocked_down"}
    assert sum(a["n_samples"] for a in auth.values()) == ev["n_samples"] and auth["at_limit"]["n_samples"] > 50
    assert auth["at_limit"]["rmse_fz_g"] == pytest.approx(auth["at_limit"]["rmse_fz_N"] * 1000 / 9.80665)
    assert sum(a["share_of_sq_error"] for a in auth.values() if a["n_samples"]) == pytest.approx(1.0)
    assert "## Per authority state" in (tmp_path / "ev" / "report.md").read_text()
    # issue 35: the residual below and above 1 Hz (their squares add up to the whole, nearly: the two parts
    # of a zero-phase split are close to orthogonal) and the 90 % interval's coverage, per set and pooled
    bands = ev["bands"]["all"]
    whole = ev["rmse_fz_N"]
    assert (bands["rmse_fz_below_1Hz_N"] ** 2 + bands["rmse_fz_above_1Hz_N"] ** 2) == pytest.approx(whole**2, rel=0.2)
    assert 0.0 < bands["coverage_90"] <= 1.0 and bands["rmse_fz_above_1Hz_g"] > 0.0
    # the part that is one constant per log lies within the slow part (a low-pass keeps a log's mean)
    assert 0.0 < bands["rmse_fz_constant_per_log_N"] <= 1.05 * bands["rmse_fz_below_1Hz_N"]
    assert "What the model cannot predict" in (tmp_path / "ev" / "report.md").read_text()
    per = ident["per_vehicle"]
    assert set(per) == {"a", "b"} and all(
        {"rmse_fz_N_before", "rmse_fz_N_calibrated", "rmse_fz_N_after", "n_samples"} <= set(v) for v in per.values()
    )
    assert ident["discovered"] == [] or isinstance(ident["discovered"], list)
    # a manifest whose flights are all test is valid for evaluate, and gives the same figures
    doc = yaml.safe_load(manifest.read_text())
    doc["flights"] = [f for f in doc["flights"] if f["split"] == "test"]
    only_test = tmp_path / "test_only.yaml"
    only_test.write_text(yaml.safe_dump(doc))
    assert main(["evaluate", str(only_test), "--model", str(model), "--out", str(tmp_path / "ev2"), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["rmse_fz_N"] == pytest.approx(ev["rmse_fz_N"], rel=1e-9)


def _one_line_exit_2(argv: list[str], capsys, *needles: str) -> None:
    from proxplan.cli import main

    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and all(n in err for n in needles), err


def test_bad_input_is_one_line_exit_2(tmp_path: Path, capsys) -> None:
    manifest = _manifest(tmp_path, n_train=1, pwm=False)
    good = {"format_version": 2, "vehicles": {TYPE: {"base": TYPE}}, "model": {"effects": []}}
    old = tmp_path / "old.yaml"
    old.write_text(yaml.safe_dump({"vehicles": {TYPE: {"base": TYPE}}}))
    _one_line_exit_2(["evaluate", str(manifest), "--model", str(old), "--out", str(tmp_path / "o")], capsys,
                     "old.yaml", "format_version")  # fmt: skip
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump(good | {"model": {"effects": [{"name": "warp_drive"}]}}))
    _one_line_exit_2(["evaluate", str(manifest), "--model", str(bad), "--out", str(tmp_path / "o")], capsys,
                     "bad.yaml", "warp_drive")  # fmt: skip
    doc = yaml.safe_load(manifest.read_text())
    for f in doc["flights"]:
        for v in f["vehicles"].values():
            v["score"] = False
    none = tmp_path / "none.yaml"
    none.write_text(yaml.safe_dump(doc))
    ok = tmp_path / "ok.yaml"
    ok.write_text(yaml.safe_dump(good))
    _one_line_exit_2(["evaluate", str(none), "--model", str(ok), "--out", str(tmp_path / "o")], capsys,
                     "none.yaml", "score: false")  # fmt: skip


def test_no_pwm_falls_back_with_one_note_and_score_false_is_source_only(tmp_path: Path, capsys) -> None:
    from proxplan.cli import main

    manifest = _manifest(tmp_path, n_train=1, pwm=False, score_b=False)
    assert main(["identify", str(manifest), "--out", str(tmp_path / "id")]) == 0
    assert capsys.readouterr().err.count("no PWM/Vbat") == 1  # identify says it once too
    ok = tmp_path / "ok.yaml"
    ok.write_text(yaml.safe_dump({"format_version": 2, "vehicles": {TYPE: {"base": TYPE}}, "model": {}}))
    assert main(["evaluate", str(manifest), "--model", str(ok), "--out", str(tmp_path / "o"), "--json"]) == 0
    cap = capsys.readouterr()
    doc = json.loads(cap.out)
    assert set(doc["per_vehicle"]) == {"a"}  # b is a source only
    assert cap.err.count("no PWM/Vbat") == 1  # the fallback is said once


def test_ninety_percent_interval_holds_on_held_out_flights(tmp_path: Path, capsys) -> None:
    """Issue 35: identify fits the residual's spread (by place in the jet) on the train flights and saves it;
    on a long held-out flight of the same world the measured force falls inside the 90 % interval in
    85-95 % of the samples (about 2 000 independent samples there: a 3-sigma band is +-2 %)."""
    from proxplan.cli import main
    from proxplan.identify import write_synthetic_manifest

    veh = BUILTIN_VEHICLES[TYPE]
    flights = []
    for k in range(4):
        t = np.arange(0.0, 60.0 if k == 3 else 20.0, 0.01)
        a = np.column_stack([0.05 * np.sin(0.6 * t + k), 0.04 * np.cos(0.5 * t), 1.3 + 0 * t])
        b = np.column_stack([0.08 * np.sin(0.9 * t + 2 * k), 0.06 * np.sin(0.7 * t), 0.9 + 0.1 * np.sin(0.4 * t + k)])
        logs = synthetic_logs({"a": veh, "b": veh}, {"a": a, "b": b}, t, accel_noise_mps2=0.03, motor_noise_N=0.002,
                              seed=k)  # fmt: skip
        flights.append((f"f{k}", "test" if k == 3 else "train", logs))
    manifest = write_synthetic_manifest(tmp_path, flights, TYPE)
    model = tmp_path / "model.yaml"
    assert main(["identify", str(manifest), "--out", str(tmp_path / "id"), "--save-model", str(model)]) == 0
    capsys.readouterr()  # identify's own report
    assert main(["evaluate", str(manifest), "--model", str(model), "--out", str(tmp_path / "ev"), "--json"]) == 0
    ev = json.loads(capsys.readouterr().out)
    assert 0.85 <= ev["bands"]["all"]["coverage_90"] <= 0.95, ev["bands"]
