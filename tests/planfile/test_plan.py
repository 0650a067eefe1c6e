"""The plan.json contract: one reader/writer, format versions, embedded vehicles and scenario, and
the one trajectory sampler."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from proxplan.fileio import UserError
from proxplan.physics import BUILTIN_VEHICLES, vehicle_from_dict
from proxplan.planfile import PLAN_FORMAT_VERSION, Plan, VehicleTrajectory, read_plan, write_plan
from proxplan.verify import scenario_of_plan


def _cubic_plan(dt_s: float = 0.05, n: int = 41) -> Plan:
    """One vehicle on a cubic path (p, v, a exact on the grid)."""
    t = np.arange(n) * dt_s
    c = np.array([[0.1, -0.2, 0.05], [0.3, 0.1, -0.02], [-0.04, 0.02, 0.01]])  # t, t^2, t^3 coefficients
    p = (
        np.column_stack([np.ones(n), np.zeros(n), np.ones(n)])
        + t[:, None] * c[0]
        + t[:, None] ** 2 * c[1]
        + t[:, None] ** 3 * c[2]
    )
    v = c[0] + 2 * t[:, None] * c[1] + 3 * t[:, None] ** 2 * c[2]
    a = 2 * c[1] + 6 * t[:, None] * c[2]
    tr = VehicleTrajectory("cf", "crazyflie-2.1", BUILTIN_VEHICLES["crazyflie-2.1"], t, p, v, a)
    return Plan("cubic", dt_s, {"cf": tr})


def test_sampler_is_exact_for_cubics_and_rests_outside_the_plan():
    plan = _cubic_plan()
    tr = plan.vehicles["cf"]
    t = np.linspace(0.0, tr.t_s[-1], 397)
    p, v, a = tr.sample(t)
    c = np.array([[0.1, -0.2, 0.05], [0.3, 0.1, -0.02], [-0.04, 0.02, 0.01]])
    want_p = np.array([1.0, 0.0, 1.0]) + t[:, None] * c[0] + t[:, None] ** 2 * c[1] + t[:, None] ** 3 * c[2]
    np.testing.assert_allclose(p, want_p, atol=1e-12)
    np.testing.assert_allclose(v, c[0] + 2 * t[:, None] * c[1] + 3 * t[:, None] ** 2 * c[2], atol=1e-10)
    np.testing.assert_allclose(a, 2 * c[1] + 6 * t[:, None] * c[2], atol=1e-8)
    p_out, v_out, a_out = tr.sample(np.array([-1.0, tr.t_s[-1] + 1.0]))
    np.testing.assert_allclose(p_out, tr.position_m[[0, -1]])
    assert not v_out.any() and not a_out.any()


def test_a_trajectory_samples_the_same_once_its_coefficients_are_kept():
    """The coefficients are computed once per trajectory: the second sampling, a copy with other
    samples (``dataclasses.replace``) and a pickled copy (which leaves them out) agree with a
    trajectory sampled fresh, bit for bit."""
    import pickle

    tr = _cubic_plan().vehicles["cf"]
    t = np.linspace(-0.1, tr.t_s[-1] + 0.1, 211)
    first = (*tr.sample(t), tr.jerk_at(t))
    again = (*tr.sample(t), tr.jerk_at(t))
    fresh = dataclasses.replace(tr)
    for x, y, z in zip(first, again, (*fresh.sample(t), fresh.jerk_at(t))):
        assert np.array_equal(x, y) and np.array_equal(x, z)
    copy = pickle.loads(pickle.dumps(tr))
    assert "_coefficients" not in copy.__dict__
    assert np.array_equal(copy.sample(t)[0], first[0])
    moved = dataclasses.replace(tr, position_m=tr.position_m + 1.0)  # new arrays: new coefficients
    np.testing.assert_allclose(moved.sample(t)[0], first[0] + 1.0, atol=1e-12)


def test_round_trip_carries_vehicle_parameters_and_the_scenario(battery_swap_plan, tmp_path):
    plan = read_plan(battery_swap_plan)
    assert plan.format_version == PLAN_FORMAT_VERSION
    heavier = dataclasses.replace(BUILTIN_VEHICLES["small-quad"], name="heavy-small", mass_kg=0.2)
    plan.vehicles["shuttle"] = dataclasses.replace(plan.vehicles["shuttle"], type_name="heavy-small", vehicle=heavier)
    write_plan(plan, tmp_path)
    doc = json.loads((tmp_path / "plan.json").read_text())
    assert doc["vehicle_types"]["heavy-small"]["mass_kg"] == 0.2  # every parameter travels with the plan
    back = read_plan(tmp_path)
    assert back.vehicles["shuttle"].vehicle == heavier
    scenario = scenario_of_plan(read_plan(battery_swap_plan))  # the plan alone gives its scenario
    assert set(scenario.vehicles) == set(plan.vehicles)
    assert scenario.limits.authority_fraction == doc["scenario_spec"]["limits"]["authority_fraction"]


def test_vehicle_yaml_form_round_trips_every_builtin():
    from proxplan.physics import vehicle_to_yaml_dict

    for name, vehicle in BUILTIN_VEHICLES.items():
        back = vehicle_from_dict(name, json.loads(json.dumps(vehicle_to_yaml_dict(vehicle))))
        assert back == vehicle, name


def _doc(plan_dir) -> dict:
    return json.loads((plan_dir / "plan.json").read_text())


@pytest.mark.parametrize(
    ("mutate", "message"),
    [
        (lambda d: d.update(format_version=99), r"format_version: 99 is not a plan format this proxplan reads"),
        (lambda d: d["vehicles"]["shuttle"].update(type="foo"), r"vehicles.shuttle.type: unknown vehicle type 'foo'"),
        (
            lambda d: d["vehicles"]["shuttle"]["position_m"][7].__setitem__(0, float("nan")),
            r"vehicles.shuttle.position_m: sample 7 is not finite",
        ),
        (
            lambda d: d["vehicles"]["carrier"]["t_s"].__setitem__(3, 0.17),
            r"vehicles.carrier.t_s: step .* between samples 2 and 3",
        ),
        (lambda d: d.pop("vehicle_types"), r"vehicle_types: expected an object"),
    ],
    ids=["version", "type", "nan", "grid", "no-types"],
)
def test_malformed_plans_are_one_line_user_errors(battery_swap_plan, tmp_path, mutate, message):
    doc = _doc(battery_swap_plan)
    mutate(doc)
    (tmp_path / "plan.json").write_text(json.dumps(doc))
    with pytest.raises(UserError, match=message) as err:
        read_plan(tmp_path / "plan.json")
    assert "\n" not in str(err.value) and str(tmp_path / "plan.json") in str(err.value)


def test_format_1_plans_read_with_builtin_types_and_say_so(battery_swap_plan, tmp_path):
    doc = _doc(battery_swap_plan)
    doc["format_version"] = 1
    del doc["vehicle_types"]
    (tmp_path / "plan.json").write_text(json.dumps(doc))
    plan = read_plan(tmp_path)
    assert plan.vehicles["carrier"].vehicle == BUILTIN_VEHICLES["large-quad"]
    assert any("plan format 1" in n for n in plan.notes)
