"""Custom vehicles from YAML: validation errors name the file and key."""

import dataclasses

import pytest

from proxplan.fileio import UserError
from proxplan.physics import load_vehicle_file, resolve_vehicle, vehicle_from_dict, vehicle_to_yaml_dict
from proxplan.physics.builtin_vehicles import LARGE_QUAD


def write(tmp_path, text):
    path = tmp_path / "vehicles.yaml"
    path.write_text(text)
    return path


def test_round_trip_of_a_builtin_vehicle():
    data = vehicle_to_yaml_dict(LARGE_QUAD)
    vehicle = vehicle_from_dict("copy", data)
    assert vehicle.to_dict()["propeller"] == LARGE_QUAD.to_dict()["propeller"]
    assert vehicle.inertia_diag_kgm2 == pytest.approx(LARGE_QUAD.inertia_diag_kgm2)


def test_base_and_override(tmp_path):
    path = write(
        tmp_path, "vehicles:\n  heavy:\n    base: large-quad\n    mass_kg: 0.9\n    propeller: {diameter_m: 0.254}\n"
    )
    heavy = load_vehicle_file(path)["heavy"]
    assert heavy.mass_kg == 0.9 and heavy.propeller.diameter_m == 0.254
    assert heavy.arm_length_m == LARGE_QUAD.arm_length_m
    assert resolve_vehicle("heavy", {"heavy": heavy}) is heavy


@pytest.mark.parametrize(
    "body, message",
    [
        ("    base: large-quad\n    mass_kg: -1\n", "vehicles.v.mass_kg: expected a positive number"),
        (
            "    base: large-quad\n    propeller: {diameter_m: 0}\n",
            "vehicles.v.propeller.diameter_m: expected a positive number",
        ),
        ("    mass_kg: 1.0\n", "vehicles.v.arm_length_m: missing; expected a positive number"),
        ("    base: nope\n", "vehicles.v.base: unknown vehicle type 'nope'"),
        ("    base: large-quad\n    colour: red\n", "vehicles.v.colour: unknown key"),
        ("    base: large-quad\n    inertia_diag_kgm2: [1, 2]\n", "inertia_diag_kgm2: expected a list of 3"),
        ("    base: large-quad\n    max_thrust_N: 5\n", "max_thrust_N: 5.0 N cannot lift"),
        ("    base: large-quad\n    mass_kg: .nan\n", "expected a finite number"),
        (
            "    base: crazyflie-2.1\n    controller: {kp_xy_Npm: 0}\n",
            "vehicles.v.controller.kp_xy_Npm: expected a positive number",
        ),
        (
            "    base: crazyflie-2.1\n    controller: {kd_z_Nspm: -0.4}\n",
            "vehicles.v.controller.kd_z_Nspm: expected a positive number",
        ),
        (
            "    base: crazyflie-2.1\n    controller: {ki_xy_Npms: -1}\n",
            "controller.ki_xy_Npms: expected a number >= 0",
        ),
        (
            "    base: crazyflie-2.1\n    controller: {kp_xy: 1.2}\n",
            "controller.kp_xy: unknown key (did you mean 'kp_xy_Npm'?)",
        ),
        (
            "    base: crazyflie-2.1\n    rotor_drag: {k_d_Ns2pradm: -1.0e-6}\n",
            "vehicles.v.rotor_drag.k_d_Ns2pradm: expected a number >= 0",
        ),
    ],
)
def test_bad_vehicles_name_file_and_key(tmp_path, body, message):
    path = write(tmp_path, "vehicles:\n  v:\n" + body)
    with pytest.raises(UserError) as err:
        load_vehicle_file(path)
    assert str(path) in str(err.value) and message in str(err.value)


def test_bad_files(tmp_path):
    with pytest.raises(UserError, match="cannot read"):
        load_vehicle_file(tmp_path / "missing.yaml")
    with pytest.raises(UserError, match="not valid YAML"):
        load_vehicle_file(write(tmp_path, "vehicles: [\n"))
    with pytest.raises(UserError, match="expected a mapping with keys vehicles"):
        load_vehicle_file(write(tmp_path, "- 1\n"))
    with pytest.raises(UserError, match="unknown vehicle type 'x'"):
        resolve_vehicle("x")


def test_effects_in_a_vehicle_file_are_reported_as_not_applied_through_vehicle_file(tmp_path):
    from proxplan.physics import vehicle_file_notes

    plain = write(tmp_path, "vehicles:\n  v: {base: small-quad}\n")
    assert vehicle_file_notes(plain) == []
    with_effects = tmp_path / "model.yaml"
    with_effects.write_text(
        "vehicles:\n  v: {base: small-quad}\nmodel:\n  effects: [{name: near_field, params: {amplitude: 1.0}}]\n"
    )
    (note,) = vehicle_file_notes(with_effects)
    assert "model_file" in note and str(with_effects) in note


def test_each_declared_section_mirrors_its_vehicle_dataclass():
    """A parameter added to a vehicle dataclass must be declared in the file format too (and back)."""
    import dataclasses

    from proxplan.physics.vehicle_yaml import SECTIONS, VehicleEntry
    from proxplan.physics.vehicles import Vehicle

    for key, (cls, part) in SECTIONS.items():
        assert list(part.model_fields) == [f.name for f in dataclasses.fields(cls)], key
    top = {f.name for f in dataclasses.fields(Vehicle)} - {"name", "sources"}
    assert set(VehicleEntry.model_fields) - {"base"} == top


def test_partial_sections_take_the_rest_from_the_base(tmp_path):
    path = write(tmp_path, "vehicles:\n  fast:\n    base: small-quad\n    kinematics: {max_speed_mps: 2.5}\n")
    fast = load_vehicle_file(path)["fast"]
    from proxplan.physics.builtin_vehicles import SMALL_QUAD

    assert fast.kinematics.max_speed_mps == 2.5
    assert fast.kinematics.max_accel_mps2 == SMALL_QUAD.kinematics.max_accel_mps2
    assert fast.tracking is None  # new limits: the base's measurement no longer describes them
    assert (
        load_vehicle_file(write(tmp_path, "vehicles:\n  same: {base: small-quad}\n"))["same"].tracking
        == SMALL_QUAD.tracking
    )


def test_controller_gains_and_rotor_drag_override_only_what_they_name(tmp_path):
    """A user's retune (kp_xy 0.8, kd_xy 0.35) keeps every other firmware default; without a base a
    vehicle gets the Crazyflie 2.1's gains scaled to its mass and RotorPy's drag scaled to its rotors;
    both round-trip through the vehicle-YAML form (plan.json, track-limits --out)."""
    from proxplan.physics import BUILTIN_VEHICLES

    cf = BUILTIN_VEHICLES["crazyflie-2.1"]
    path = write(
        tmp_path,
        "vehicles:\n  retuned:\n    base: crazyflie-2.1\n    controller: {kp_xy_Npm: 0.8, kd_xy_Nspm: 0.35}\n"
        "    rotor_drag: {k_z_Ns2pradm: 0.0}\n",
    )
    retuned = load_vehicle_file(path)["retuned"]
    assert retuned.controller.kp_xy_Npm == 0.8 and retuned.controller.kd_xy_Nspm == 0.35
    assert retuned.controller.kp_z_Npm == cf.controller.kp_z_Npm == 1.25
    assert retuned.rotor_drag.k_d_Ns2pradm == cf.rotor_drag.k_d_Ns2pradm and retuned.drag_rate_ps[2] == 0.0
    again = vehicle_from_dict("retuned", vehicle_to_yaml_dict(retuned))
    assert again.controller == retuned.controller and again.rotor_drag == retuned.rotor_drag
    bare = {k: v for k, v in vehicle_to_yaml_dict(LARGE_QUAD).items() if k not in ("rotor_drag", "controller")}
    derived = vehicle_from_dict("bare", bare)  # an older file: no rotor_drag / controller keys
    assert dataclasses.astuple(derived.controller) == pytest.approx(dataclasses.astuple(LARGE_QUAD.controller))
    assert derived.drag_rate_ps == pytest.approx(LARGE_QUAD.drag_rate_ps)
