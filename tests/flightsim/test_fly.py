"""Plans that hold when flown: trackable limits, the tracking tube, flown vs predicted reports and
feed-forward of the predicted disturbance (docs/flying.md)."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from proxplan.cli import main
from proxplan.flightsim import SimulationOptions, simulate_plan, simulation_metrics
from proxplan.flightsim.report import feedforward_comparison
from proxplan.flightsim.tracking import course_tracking_error_m
from proxplan.physics import BUILTIN_VEHICLES
from proxplan.planfile import load_scenario, plan_from_dict, plan_to_dict, read_plan, write_plan
from proxplan.planner import plan_scenario
from proxplan.verify import wrench_along_plan

SCENARIOS = Path(__file__).resolve().parents[2] / "scenarios"
QUIET = SimulationOptions(imu_noise=False)


def _plan(name: str):
    scenario = load_scenario(SCENARIOS / f"{name}.yaml")
    return scenario, plan_scenario(scenario, method="sampling", seed=0)


def test_builtin_limits_are_tracked_within_the_type_tube():
    vehicle = BUILTIN_VEHICLES["crazyflie-2.1"]
    err = course_tracking_error_m(vehicle)
    assert err < vehicle.tracking_tube_m  # the tube covers what the default controller does at the limits
    assert vehicle.tracking_tube_m < 0.06  # smaller than the single figure every plan used before


def test_plan_carries_feedforward_and_old_files_recompute_it(tmp_path):
    scenario, plan = _plan("battery_swap")
    carrier = plan.vehicles["carrier"]
    assert carrier.has_feedforward
    along = wrench_along_plan(plan, scenario, t_s=plan.t_s)
    np.testing.assert_allclose(carrier.disturbance_force_N, along["carrier"].force_N, atol=1e-6)
    assert carrier.disturbance_force_N[-1, 2] < -0.1  # docked shuttle above pushes the carrier down
    assert plan.metrics["tracking_margin_m"] == scenario.limits.tracking_margin_m
    assert plan.scenario_spec is not None and "tracking_margin_m" in plan.scenario_spec["limits"]
    # written and read back
    back = read_plan(write_plan(plan, tmp_path))
    np.testing.assert_allclose(back.vehicles["carrier"].disturbance_torque_Nm, carrier.disturbance_torque_Nm, atol=1e-7)
    # an older file without the fields: read fine, recomputed (and said so) for feed-forward
    doc = plan_to_dict(plan)
    for v in doc["vehicles"].values():
        v.pop("disturbance_force_N")
        v.pop("disturbance_torque_Nm")
    old = plan_from_dict(doc)
    assert not old.vehicles["carrier"].has_feedforward
    res = simulate_plan(old, options=dataclasses.replace(QUIET, feedforward=True))
    assert any("recomputed" in n for n in res.notes)
    np.testing.assert_allclose(
        res.records["carrier"].predicted_force_N[-1], carrier.disturbance_force_N[-1], rtol=1e-3, atol=1e-6
    )


@pytest.mark.parametrize("name", ["battery_swap", "handoff"])
def test_feedforward_cuts_the_most_disturbed_altitude_error(name):
    scenario, plan = _plan(name)
    without = simulate_plan(plan, options=QUIET)
    with_ff = simulate_plan(plan, options=dataclasses.replace(QUIET, feedforward=True))
    cmp = feedforward_comparison(without, with_ff)
    worst = cmp["most_disturbed"]
    factor = cmp["vehicles"][worst]["altitude_error_factor"]
    # issue: >= 3x. Measured 12.9x (battery swap) and 5.3x (hand-off): at the measured limits (1.5 m/s)
    # the receiver's own climbs leave a tracking error the disturbance feed-forward cannot remove
    # (it was 15-22x at 1 m/s, 1 m/s^2 with RotorPy's law); 4x keeps a margin over the 3x.
    assert factor is not None and factor >= 4.0, cmp
    # flown usage stays within the scenario's limit and next to the prediction
    metrics = simulation_metrics(with_ff)
    for m in metrics.values():
        assert m.max_authority_usage <= scenario.limits.authority_fraction
    assert metrics[worst].predicted_max_authority_usage > 0.0


def test_simulate_feedforward_command_reports_both(tmp_path, capsys):
    scenario, plan = _plan("battery_swap")
    doc = plan_to_dict(plan)
    for v in doc["vehicles"].values():  # an older plan.json
        del v["disturbance_force_N"], v["disturbance_torque_Nm"]
    (tmp_path / "p").mkdir()
    (tmp_path / "p" / "plan.json").write_text(json.dumps(doc))
    code = main(
        ["simulate", str(tmp_path / "p"), "--out", str(tmp_path / "s"), "--feedforward", "--no-noise", "--json"]
    )
    assert code == 0
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert any("recomputed" in n for n in out["notes"])
    ff = out["feedforward"]
    carrier = ff["vehicles"]["carrier"]
    assert carrier["with"]["max_altitude_error_m"] < carrier["without"]["max_altitude_error_m"]
    v = out["vehicles"]["carrier"]
    for key in ("predicted_max_authority_usage", "predicted_time_in_invalid_zone_s", "usage_ratio_flown_to_predicted"):
        assert key in v
    assert (tmp_path / "s" / "summary.json").exists()


@pytest.mark.slow
@pytest.mark.parametrize("path", sorted(SCENARIOS.glob("*.yaml")), ids=lambda p: p.stem)
def test_shipped_scenario_holds_when_flown(path):
    """Flown (truth = the planner's model, default controller): every vehicle's max authority usage
    <= the scenario's limit, and no invalid-zone entry the plan avoided."""
    scenario = load_scenario(path)
    plan = plan_scenario(scenario, method="sampling", seed=0)
    metrics = simulation_metrics(simulate_plan(plan, options=QUIET))
    for name, m in metrics.items():
        assert m.max_authority_usage <= scenario.limits.authority_fraction, (name, m)
        if m.predicted_time_in_invalid_zone_s == 0.0:
            assert m.time_in_invalid_zone_s == 0.0, (name, m)


def test_a_flight_without_feedforward_is_not_changed_by_an_earlier_one():
    _, plan = _plan("battery_swap")
    first = simulate_plan(plan, options=QUIET)
    simulate_plan(plan, options=dataclasses.replace(QUIET, feedforward=True))  # same cached stepper
    again = simulate_plan(plan, options=QUIET)
    for name, rec in first.records.items():
        np.testing.assert_allclose(again.records[name].position_m, rec.position_m, atol=1e-9)


@pytest.mark.slow
@pytest.mark.parametrize("path", sorted(SCENARIOS.glob("*.yaml")), ids=lambda p: p.stem)
def test_shipped_scenario_exported_and_flown_stays_within_2_cm_where_undisturbed(path, tmp_path):
    """Issue 31: exported for the Crazyflie (drag-compensated uploads), read back and flown (the
    uploads themselves, Mellinger law with rotor drag), every vehicle stays within 2 cm of the plan
    wherever the plan predicts no disturbance on it; the export passes verify."""
    from proxplan.export import export_crazyflie
    from proxplan.flightsim.report import predicted_deflection_m, undisturbed
    from proxplan.planfile import read_export
    from proxplan.verify import verify_plan

    scenario = load_scenario(path)
    plan = plan_scenario(scenario, method="sampling", seed=0)
    export_crazyflie(plan, scenario, tmp_path)
    back = read_export(tmp_path)
    assert verify_plan(back, scenario) == []
    checked = 0
    for name, rec in simulate_plan(back, options=QUIET).records.items():
        err = np.linalg.norm(rec.position_m - plan.vehicles[name].position_at(rec.t_s), axis=1)
        calm = undisturbed(rec, predicted_deflection_m(rec))
        if calm.any():  # (a vehicle under another one from start to end has no such stretch)
            assert err[calm].max() <= 0.02, (name, float(err[calm].max()))
            checked += 1
    assert checked >= 1
