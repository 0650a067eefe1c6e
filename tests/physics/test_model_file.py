"""The calibrated model file (proxplan.physics.model_file): round trip, older format, bad input."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from proxplan.fileio import UserError
from proxplan.physics import (
    BUILTIN_VEHICLES,
    EFFECT_NAMES,
    CalibratedModel,
    Effect,
    ModelOptions,
    load_model_file,
    target_only_notes,
    write_model_file,
)


def _model() -> CalibratedModel:
    small = dataclasses.replace(BUILTIN_VEHICLES["small-quad"], mass_kg=0.0371)
    return CalibratedModel(
        vehicles={"small-quad": small, "large-quad": BUILTIN_VEHICLES["large-quad"]},
        options=ModelOptions(field_form="printed"),
        effects=(
            Effect("thrust_bias", {"force_z_N": -0.012}),
            Effect("near_field", {"amplitude": 0.7, "decay_L": 2.5}),
            Effect("wake_memory", {"share_1": 0.2, "lag_s": 0.31}),  # a delay is saved with its effect
        ),
        thrust_scales={"small-quad": 1.031, "large-quad": 0.987},
        uncertainty={"small-quad.c_ax": 0.21},
    )


def test_round_trip_keeps_every_part(tmp_path: Path) -> None:
    model = _model()
    path = write_model_file(model, tmp_path / "m.yaml")
    back = load_model_file(path)
    assert back == model
    assert back.vehicles["small-quad"].mass_kg == pytest.approx(0.0371)
    assert back.notes == ()
    assert [e.name for e in back.between_vehicle_effects] == ["near_field", "wake_memory"]
    assert back.effects[2].lag_s == pytest.approx(0.31)
    (note,) = target_only_notes(back, "m.yaml")
    assert "thrust_bias" in note and "near_field" not in note


def test_older_format_without_version_is_read_with_a_note(tmp_path: Path) -> None:
    path = tmp_path / "old.yaml"
    path.write_text(
        "vehicles:\n  small-quad: {base: small-quad}\n"
        "model:\n  field_form: inverse-z\n  effects: [{name: near_field, params: {amplitude: 1.0}}]\n"
    )
    model = load_model_file(path)
    assert model.format_version == 1 and model.thrust_scales == {}
    assert model.effects == (Effect("near_field", {"amplitude": 1.0}),)
    (note,) = model.notes
    assert str(path) in note and "format_version" in note


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("format_version: 99\nvehicles: {}\n", "format_version: 99"),
        ("vehicles: {}\nmodel: {effects: [{name: vortex_ring}]}\n", "model.effects\\[0\\].name: unknown effect"),
        (
            "vehicles: {}\nmodel: {effects: [{name: near_field, params: {x: 1}}]}\n",
            "params.x: unknown parameter of near_field",
        ),
        (
            "vehicles: {}\nmodel: {effects: [{name: near_field, params: {lag_s: -0.2}}]}\n",
            "params.lag_s: expected a delay in \\[0, 2\\] s",
        ),
        ("vehicles: {}\nmodel: {thrust_scales: {a: -1}}\n", "model.thrust_scales.a"),
        ("vehicles: {}\nmodel: {field_form: wide}\n", "model.field_form"),
        ("vehicles: {}\nmodel: {colour: red}\n", "model.colour: unknown key"),
        ("effects: []\n", "effects: unknown key"),
        ("format_version: 2\n", "vehicles: missing"),
    ],
)
def test_bad_input_is_one_line_error_naming_file_and_key(tmp_path: Path, text: str, match: str) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(UserError, match=match) as info:
        load_model_file(path)
    assert str(path) in str(info.value) and "\n" not in str(info.value)
    if "unknown effect" in match:
        assert all(name in str(info.value) for name in EFFECT_NAMES)
