"""Trackable limits and tracking tube measured per vehicle type (proxplan.flightsim.tracking)."""

from __future__ import annotations

import dataclasses
import json

import pytest

from proxplan.cli import main
from proxplan.flightsim.tracking import fly_course, measure_tracking, thrust_accel_limit_mps2
from proxplan.physics import BUILTIN_VEHICLES, KinematicLimits, load_vehicle_file

CF = BUILTIN_VEHICLES["crazyflie-2.1"]
SLOW = KinematicLimits(0.5, 0.5, 2.0)
FAST = KinematicLimits(1.5, 2.5, 10.0)


def test_measurement_keeps_the_fastest_level_within_the_budget_and_records_how():
    q_slow, _, _, _ = fly_course(CF, SLOW)
    q_fast, _, _, _ = fly_course(CF, FAST)
    assert q_slow < q_fast  # faster limits, larger error (the mechanism the ladder relies on)
    budget = 0.5 * (q_slow + q_fast) + 0.005  # between the two levels' error + margin
    res = measure_tracking(CF, budget_m=budget, margin_m=0.005, levels=[SLOW, FAST])
    assert res.vehicle.kinematics == SLOW
    m = res.vehicle.tracking
    assert m is not None and m.controller == "mellinger"
    assert m.tube_m == pytest.approx(q_slow + 0.005, abs=1e-4)
    assert res.vehicle.tracking_tube_m == m.tube_m
    assert "budget" in m.limited_by and "1.5 m/s" in m.limited_by
    # a budget above both keeps the faster level
    wide = measure_tracking(CF, budget_m=q_fast + 0.01, margin_m=0.005, levels=[SLOW, FAST])
    assert wide.vehicle.kinematics == FAST
    with pytest.raises(ValueError, match="no level"):
        measure_tracking(CF, budget_m=0.5 * q_slow, margin_m=0.0, levels=[SLOW])


def test_levels_beyond_thrust_to_weight_are_not_flown():
    cap = thrust_accel_limit_mps2(CF)  # m (g + a) <= 0.8 T_max: (0.8 x 1.83 - 1) g = 4.6 m/s^2
    assert 4.0 < cap < 5.0
    res = measure_tracking(CF, budget_m=0.5, levels=[SLOW, KinematicLimits(1.0, cap + 1.0, 20.0)])
    over = res.flights[1]
    assert not over.allowed and "thrust-to-weight" in over.reason
    assert res.vehicle.kinematics == SLOW


def test_builtin_types_carry_their_measurement_and_tube():
    for v in BUILTIN_VEHICLES.values():
        m = v.tracking
        assert m is not None and m.controller == "mellinger"
        assert m.tube_m == pytest.approx(m.quantile_error_m + m.margin_m, abs=1e-4)
        assert m.tube_m <= m.budget_m
    k = CF.kinematic_limits  # issue 31: a tube <= 2 cm at >= 1.5 m/s and >= 3 m/s^2
    assert k.max_speed_mps >= 1.5 and k.max_accel_mps2 >= 3.0 and CF.tracking_tube_m <= 0.02


def test_track_limits_cli_writes_a_vehicle_file(tmp_path, capsys, monkeypatch):
    import proxplan.flightsim.tracking as tracking

    monkeypatch.setattr(tracking, "ladder", lambda: [SLOW, FAST])  # two flights instead of the full ladder
    out = tmp_path / "measured.yaml"
    code = main(["track-limits", "--vehicle", "crazyflie-2.1", "--budget", "0.2", "--out", str(out), "--json"])
    assert code == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["kinematic_limits"] == dataclasses.asdict(FAST)
    loaded = load_vehicle_file(out)["crazyflie-2.1"]
    assert loaded.kinematics == FAST and loaded.tracking is not None
    assert loaded.tracking.tube_m == doc["tracking_tube_m"]
    assert "track-limits" in loaded.tracking.command


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(BUILTIN_VEHICLES))
def test_builtin_measurement_reproduces(name):
    """Re-measuring a built-in type gives its stored limits and tube."""
    v = BUILTIN_VEHICLES[name]
    res = measure_tracking(v, budget_m=v.tracking.budget_m, margin_m=v.tracking.margin_m)
    assert res.vehicle.kinematics == v.kinematics
    assert res.vehicle.tracking.tube_m == pytest.approx(v.tracking.tube_m, abs=1e-3)


def test_drag_compensation_keeps_the_course_within_the_tube_and_switched_off_it_does_not():
    """At the crazyflie-2.1's measured limits the compensated reference is tracked within the tube;
    flying the plan itself (the lag c m v / k_p, ~1.9 cm per m/s) is not, by a wide margin."""
    q, mx, _, _ = fly_course(CF, CF.kinematic_limits)
    assert q + CF.tracking.margin_m <= CF.tracking_tube_m + 1e-4 and mx < CF.tracking_tube_m
    _, plain, _, _ = fly_course(CF, CF.kinematic_limits, drag_compensation=False)
    assert plain > 2.0 * CF.tracking_tube_m, (mx, plain)


def test_track_limits_rejects_a_vehicle_file_with_a_bad_gain_or_drag(tmp_path, capsys):
    for section, message in (
        ("controller: {kp_xy_Npm: 0}", "controller.kp_xy_Npm: expected a positive number"),
        ("rotor_drag: {k_d_Ns2pradm: -1.0e-6}", "rotor_drag.k_d_Ns2pradm: expected a number >= 0"),
    ):
        path = tmp_path / "v.yaml"
        path.write_text(f"vehicles:\n  mine:\n    base: crazyflie-2.1\n    {section}\n")
        assert main(["track-limits", "--vehicle", "mine", "--vehicles", str(path)]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and message in err and str(path) in err
