"""`proxplan verify` trusts nothing in a plan.json: edited plans fail, naming vehicle, sample and check."""

from __future__ import annotations

import json

import numpy as np


def _write(tmp_path, doc) -> str:
    path = tmp_path / "plan.json"
    path.write_text(json.dumps(doc))
    return str(path)


def test_a_one_metre_jump_between_samples_fails_naming_vehicle_sample_and_check(battery_swap_plan, tmp_path, proxplan):
    doc = json.loads((battery_swap_plan / "plan.json").read_text())
    k = 30
    doc["vehicles"]["shuttle"]["position_m"][k][0] += 1.0  # one sample jumps 1 m, 0.05 s from its neighbours
    res = proxplan("verify", _write(tmp_path, doc), "--json")
    assert res.returncode == 1, res.stderr
    found = [
        v for v in json.loads(res.stdout)["violations"] if v["vehicle"] == "shuttle" and v["kind"] == "consistency"
    ]
    assert found and found[0]["sample"] in (k - 1, k), found
    text = proxplan("verify", _write(tmp_path, doc))
    assert text.returncode == 1 and f"(sample {found[0]['sample']}) shuttle: consistency" in text.stdout


def test_a_jump_with_doctored_velocities_still_fails_on_the_implied_speed(battery_swap_plan, tmp_path, proxplan):
    """Positions and velocities edited together stay inconsistent with the accelerations and the
    speed the positions imply."""
    doc = json.loads((battery_swap_plan / "plan.json").read_text())
    t = np.asarray(doc["vehicles"]["shuttle"]["t_s"])
    p = np.asarray(doc["vehicles"]["shuttle"]["position_m"])
    p[40:] += [1.0, 0.0, 0.0]
    doc["vehicles"]["shuttle"]["position_m"] = p.tolist()
    doc["vehicles"]["shuttle"]["velocity_mps"] = np.gradient(p, t, axis=0).tolist()
    res = proxplan("verify", _write(tmp_path, doc), "--json")
    assert res.returncode == 1
    kinds = {(v["vehicle"], v["kind"]) for v in json.loads(res.stdout)["violations"]}
    assert ("shuttle", "speed") in kinds and ("shuttle", "consistency") in kinds


def test_an_unknown_vehicle_type_fails(battery_swap_plan, tmp_path, proxplan):
    doc = json.loads((battery_swap_plan / "plan.json").read_text())
    doc["vehicles"]["shuttle"]["type"] = "foo"
    res = proxplan("verify", _write(tmp_path, doc))
    assert res.returncode == 2 and "Traceback" not in res.stderr
    assert res.stderr.count("\n") == 1 and "vehicles.shuttle.type: unknown vehicle type 'foo'" in res.stderr


def test_a_swapped_vehicle_type_fails_against_the_scenario(battery_swap_plan, tmp_path, proxplan):
    """The type is known (its parameters are in the plan) but is not what the scenario's task flies."""
    doc = json.loads((battery_swap_plan / "plan.json").read_text())
    doc["vehicles"]["shuttle"]["type"] = "large-quad"
    res = proxplan("verify", _write(tmp_path, doc), "--json")
    assert res.returncode == 1
    v = json.loads(res.stdout)["violations"]
    assert [(x["vehicle"], x["kind"], x["sample"]) for x in v] == [("shuttle", "vehicle-type", 0)]


def test_an_unknown_format_version_is_one_line(battery_swap_plan, tmp_path, proxplan):
    doc = json.loads((battery_swap_plan / "plan.json").read_text())
    doc["format_version"] = 99
    res = proxplan("verify", _write(tmp_path, doc))
    assert res.returncode == 2 and res.stderr.count("\n") == 1
    assert "format_version: 99" in res.stderr and "Traceback" not in res.stderr


def test_a_plan_that_starts_elsewhere_fails(battery_swap_plan, tmp_path, proxplan):
    doc = json.loads((battery_swap_plan / "plan.json").read_text())
    p = np.asarray(doc["vehicles"]["shuttle"]["position_m"]) + [0.0, 0.3, 0.0]  # the whole path shifted
    doc["vehicles"]["shuttle"]["position_m"] = p.tolist()
    res = proxplan("verify", _write(tmp_path, doc), "--json")
    kinds = {(v["vehicle"], v["kind"]) for v in json.loads(res.stdout)["violations"]}
    assert res.returncode == 1 and ("shuttle", "start") in kinds
