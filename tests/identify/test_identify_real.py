"""The shipped Neural-Swarm manifest on the real logs (skips when ../shared is absent)."""

from __future__ import annotations

from pathlib import Path

import pytest

SHARED = Path(__file__).resolve().parents[2].parent / "shared"
MANIFEST = Path(__file__).resolve().parents[2] / "manifests" / "neural-swarm.yaml"
DATA = SHARED / "data" / "neural-swarm"
ABSENT = (f"Neural-Swarm flight logs not found at {DATA}: they come from the public aerorobotics/neural-swarm "
          "repository and are read from ../shared/data/neural-swarm beside the repository (its README), never "
          "copied into it")  # fmt: skip


@pytest.mark.slow  # the whole pipeline on every shipped set (minutes on a shared machine)
@pytest.mark.skipif(not DATA.is_dir(), reason=ABSENT)
def test_real_manifest_after_beats_before(tmp_path: Path) -> None:
    from proxplan.identify import load_manifest, run_identify

    manifest = load_manifest(MANIFEST)
    train_runs = {f.name for f in manifest.flights if f.split == "train"}
    test_runs = {f.name for f in manifest.flights if f.split == "test"}
    assert train_runs and test_runs and not train_runs & test_runs
    train_logs = {v.log for f in manifest.flights if f.split == "train" for v in f.vehicles}
    assert not train_logs & {v.log for f in manifest.flights if f.split == "test" for v in f.vehicles}
    result = run_identify(manifest, thrust_summary=False)
    assert result.after.rmse_fz_N < result.before.rmse_fz_N
    assert result.after.n_samples == result.before.n_samples > 1000
    # the swaps are partly inside 3 L of the source: reported, not hidden
    assert result.validity["samples_below_a_source"] > 0
    # issue 13: the delivered thrust finds saturated motors on the real logs, and the saved model
    # reproduces identify's "after" on the same test flights without refitting
    from proxplan.identify import evaluate_model

    sat = result.measurement_json()["saturation"]
    assert all(s["thrust_source"] == "pwm" for s in sat.values())
    assert sat["cf101"]["saturated_samples"] > 100
    ev = evaluate_model(manifest, result.saved())
    doc = ev.to_json()
    assert doc["rmse_fz_N"] == pytest.approx(result.after.rmse_fz_N, rel=0.01)
    assert doc["n_samples"] == result.after.n_samples
    assert doc["scored_fraction"] > 0.9
    assert set(result.per_vehicle) == set(doc["per_vehicle"])
    # issue 24: three-vehicle swaps are scored per set and per number of sources overhead; the
    # stack-shielding parameter is chosen on validation stacks, and the stacks' error is below no model
    assert {"swap_sss", "swap_ssl", "swap_sll", "swap_lll"} <= set(doc["sets"])
    assert doc["overhead"]["2+"]["n_samples"] > 1000
    assert doc["overhead"]["2+"]["ratio_fz"] < 1.0
    assert result.stack_shielding is not None and result.stack_shielding["prior"]["informed"]  # the stacks inform eta
    assert "cf100" not in doc["per_vehicle"]  # swap_lll's cf100 is a source only (its IMU is unusable)
    # issue 29: another day's flights validate (they fit nothing), the measurement agrees with its
    # declared motor lag, and every effect trial says why it was kept or rejected
    assert "4 validation flights held out" in result.validation and "by flight" in result.validation
    assert result.motor_lag_check["warnings"] == []
    assert all(t.reason for t in result.trials)
    assert sat["cf102"]["floored_samples"] > 100


@pytest.mark.skipif(not DATA.is_dir(), reason=ABSENT)
def test_real_floor_spike_is_gone() -> None:
    """Issue 29: on the day-21 train flight swap_lll_01 the bottom vehicle cf102 is knocked down and its
    motors hit both limits; with u[N] read as thrust at PWM 0 the measured F_z showed a false +0.60 N
    spike. With the delivered thrust at both limits it stays below 0.2 N (the largest real upward push
    in the flight is a ground-effect / bounce-free +0.09 N)."""
    from dataclasses import replace

    from proxplan.identify import load_manifest
    from proxplan.identify.loading import load_units

    manifest = load_manifest(MANIFEST)
    one = replace(manifest, flights=tuple(f for f in manifest.flights if f.name == "swap_lll_01"))
    data = load_units(one, thrust_coefficient_samples=False)
    cf102 = next(u for u in data.units if u.name == "cf102")
    excl = data.exclusions["swap_lll_01"]["cf102"]
    assert excl["floored_samples"] > 10 and excl["saturated_samples"] > 10  # both limits are met
    assert cf102.force_N[:, 2].max() < 0.2  # N
