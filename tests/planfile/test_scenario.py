"""Scenario loading and validation: shipped files load; bad files give the documented one-line errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from proxplan.fileio import UserError
from proxplan.physics import BUILTIN_VEHICLES
from proxplan.planfile import Limits, load_scenario

SCENARIOS = Path(__file__).resolve().parents[2] / "scenarios"

GOOD = {
    "name": "t",
    "workspace": {"min": [-3, -3, 0], "max": [3, 3, 4]},
    "obstacles": [{"min": [1, -0.5, 0], "max": [1.5, 0.5, 2]}],
    "limits": {"authority_fraction": 0.4, "min_separation_m": 0.3},
    "vehicles": {
        "carrier": {"type": "large-quad", "start": [0, 0, 1.5], "hover": True},
        "shuttle": {"type": "small-quad", "start": [2, 1, 2.5], "dock": {"with": "carrier", "offset": [0, 0, 0.4]}},
        "other": {"type": "small-quad", "start": [-2, 0, 1], "goal": [2, 0, 2.5], "max_speed_mps": 0.7},
    },
}


def _write(tmp_path: Path, doc: dict, name: str = "s.yaml") -> Path:
    path = tmp_path / name
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def _bad(tmp_path: Path, mutate) -> str:
    import copy

    doc = copy.deepcopy(GOOD)
    mutate(doc)
    path = _write(tmp_path, doc)
    with pytest.raises(UserError) as err:
        load_scenario(path)
    msg = str(err.value)
    assert str(path) in msg, msg  # every message names the file
    assert "\n" not in msg
    return msg


def test_design_example_loads_with_defaults_and_overrides(tmp_path):
    sc = load_scenario(_write(tmp_path, GOOD))
    assert list(sc.vehicles) == ["carrier", "shuttle", "other"]  # file order kept
    assert sc.limits.authority_fraction == 0.4 and sc.limits.invalid_zone_rule == Limits().invalid_zone_rule
    other = sc.vehicles["other"]
    assert other.max_speed_mps == 0.7  # override
    assert other.max_accel_mps2 == BUILTIN_VEHICLES["small-quad"].kinematic_limits.max_accel_mps2  # default per type
    carrier = sc.vehicles["carrier"]
    assert carrier.max_accel_mps2 == BUILTIN_VEHICLES["large-quad"].kinematic_limits.max_accel_mps2  # its type's
    np.testing.assert_allclose(sc.final_position_m("shuttle"), [0, 0, 1.9])
    assert sc.dock_order().index("carrier") < sc.dock_order().index("shuttle")
    assert sc.spec["vehicles"]["other"]["goal"] == [2, 0, 2.5]


def test_unknown_key(tmp_path):
    msg = _bad(tmp_path, lambda d: d["vehicles"]["other"].update(speed=3))
    assert "vehicles.other.speed" in msg and "unknown key" in msg and "max_speed_mps" in msg


def test_unknown_top_level_key(tmp_path):
    msg = _bad(tmp_path, lambda d: d.update(vehicle=1))
    assert "vehicle" in msg and "unknown key" in msg and "vehicles" in msg


def test_unknown_vehicle_type(tmp_path):
    msg = _bad(tmp_path, lambda d: d["vehicles"]["other"].update(type="hexa"))
    assert "vehicles.other.type" in msg and "'hexa'" in msg and "small-quad" in msg


def test_start_outside_workspace(tmp_path):
    msg = _bad(tmp_path, lambda d: d["vehicles"]["other"].update(start=[-5, 0, 1]))
    assert "vehicles.other.start" in msg and "outside the workspace" in msg


def test_start_inside_obstacle(tmp_path):
    msg = _bad(tmp_path, lambda d: d["vehicles"]["other"].update(start=[1.2, 0, 1]))
    assert "vehicles.other.start" in msg and "obstacles[0]" in msg and "free space" in msg


def test_goal_inside_obstacle(tmp_path):
    msg = _bad(tmp_path, lambda d: d["vehicles"]["other"].update(goal=[1.2, 0, 1]))
    assert "vehicles.other.goal" in msg and "obstacles[0]" in msg


def test_dock_target_missing(tmp_path):
    msg = _bad(tmp_path, lambda d: d["vehicles"]["shuttle"]["dock"].update({"with": "ghost"}))
    assert "vehicles.shuttle.dock.with" in msg and "'ghost'" in msg and "carrier" in msg


def test_dock_cycle(tmp_path):
    def mutate(d):
        d["vehicles"]["carrier"] = {
            "type": "large-quad",
            "start": [0, 0, 1.5],
            "dock": {"with": "shuttle", "offset": [0, 0, -0.4]},
        }

    msg = _bad(tmp_path, mutate)
    assert "cycle" in msg and "dock.with" in msg


def test_dock_with_itself(tmp_path):
    msg = _bad(tmp_path, lambda d: d["vehicles"]["shuttle"]["dock"].update({"with": "shuttle"}))
    assert "itself" in msg


def test_exactly_one_task(tmp_path):
    msg = _bad(tmp_path, lambda d: d["vehicles"]["other"].pop("goal"))
    assert "exactly one of" in msg and "vehicles.other" in msg
    msg = _bad(tmp_path, lambda d: d["vehicles"]["other"].update(hover=True))
    assert "exactly one of" in msg


def test_bad_vector_and_limits(tmp_path):
    msg = _bad(tmp_path, lambda d: d["vehicles"]["other"].update(start=[0, 1]))
    assert "vehicles.other.start" in msg and "3 finite numbers" in msg
    msg = _bad(tmp_path, lambda d: d["limits"].update(authority_fraction=1.5))
    assert "limits.authority_fraction" in msg and "(0, 1]" in msg
    msg = _bad(tmp_path, lambda d: d["limits"].update(invalid_zone_rule="ignore"))
    assert "limits.invalid_zone_rule" in msg and "conservative" in msg
    msg = _bad(tmp_path, lambda d: d.pop("workspace"))
    assert "workspace" in msg and "missing" in msg


def test_not_yaml_and_missing_file(tmp_path):
    path = tmp_path / "x.yaml"
    path.write_text("vehicles: [unclosed")
    with pytest.raises(UserError, match="not valid YAML"):
        load_scenario(path)
    with pytest.raises(UserError, match="cannot read scenario file"):
        load_scenario(tmp_path / "missing.yaml")


def test_vehicle_file_relative_to_scenario(tmp_path):
    sub = tmp_path / "cfg"
    sub.mkdir()
    (sub / "fleet.yaml").write_text(
        yaml.safe_dump({"vehicles": {"heavy-small": {"base": "small-quad", "mass_kg": 0.2}}})
    )
    import copy

    doc = copy.deepcopy(GOOD)
    doc["vehicle_file"] = "fleet.yaml"
    doc["vehicles"]["other"]["type"] = "heavy-small"
    sc = load_scenario(_write(sub, doc))
    assert sc.vehicles["other"].vehicle.mass_kg == pytest.approx(0.2)
    doc["vehicle_file"] = "nope.yaml"
    with pytest.raises(UserError, match="vehicle_file"):
        load_scenario(_write(sub, doc, "t2.yaml"))


@pytest.mark.parametrize("path", sorted(SCENARIOS.glob("*.yaml")), ids=lambda p: p.stem)
def test_shipped_scenarios_load_and_start_with_a_comment(path):
    assert path.read_text().startswith("#"), f"{path.name} must start with a comment saying what it tests"
    sc = load_scenario(path)
    assert sc.vehicles and sc.source_path == str(path.resolve())


def test_assign_goals_is_parsed_checked_and_carried_in_the_spec(tmp_path):
    import copy

    from proxplan.planfile import scenario_from_dict

    assert load_scenario(_write(tmp_path, GOOD)).assign_goals is None  # absent: fixed goals
    doc = copy.deepcopy(GOOD)
    doc["assign_goals"] = "by_type"
    sc = load_scenario(_write(tmp_path, doc))
    assert sc.assign_goals == "by_type" and sc.to_spec()["assign_goals"] == "by_type"
    assert scenario_from_dict(sc.to_spec(), label="spec").assign_goals == "by_type"  # plan.json round trip
    assert "assign_goals" not in load_scenario(_write(tmp_path, GOOD)).to_spec()
    msg = _bad(tmp_path, lambda d: d.update(assign_goals="by_name"))
    assert "assign_goals: expected by_type, got 'by_name'" in msg


def test_misspelt_keys_name_the_key_path_and_suggest_the_known_key(tmp_path):
    msg = _bad(tmp_path, lambda d: d["vehicles"]["shuttle"]["dock"].update(ofset=[0, 0, 1]))
    assert "vehicles.shuttle.dock.ofset: unknown key (did you mean 'offset'?)" in msg
    msg = _bad(tmp_path, lambda d: d["obstacles"][0].update(mx=[1, 1, 1]))
    assert "obstacles[0].mx: unknown key (did you mean 'max'?)" in msg
    msg = _bad(tmp_path, lambda d: d.update(limit={}))
    assert "limit: unknown key (did you mean 'limits'?)" in msg


def test_numbers_are_not_converted_and_names_may_be_numbers(tmp_path):
    msg = _bad(tmp_path, lambda d: d["limits"].update(min_separation_m="0.3"))
    assert "limits.min_separation_m: expected a number in (0, 10], got '0.3'" in msg
    msg = _bad(tmp_path, lambda d: d["vehicles"]["other"].update(max_speed_mps=True))
    assert "vehicles.other.max_speed_mps: expected a number in (0, 20], got True" in msg
    msg = _bad(
        tmp_path, lambda d: d["vehicles"].update({7: {"type": "small-quad", "start": [0, 2, 1], "hover": "yes"}})
    )
    assert "vehicles.7.hover: expected true or false, got 'yes'" in msg
