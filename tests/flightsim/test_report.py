"""Metrics and plot of a simulated flight; the torque of a truth effect seen in the logs (S0-13)."""

from __future__ import annotations

import numpy as np

from proxplan.flightsim import hover_stack_plan, simulate_plan
from proxplan.flightsim.report import motor_usage, plot_errors, simulation_metrics
from proxplan.physics import BUILTIN_VEHICLES, Effect, authority_usage


def test_metrics_of_a_stack_and_the_invalid_zone(tmp_path):
    far = simulate_plan(hover_stack_plan(separation_m=1.5, duration_s=2.0), imu_noise=False)
    m = simulation_metrics(far)
    rec = far.records["bottom"]
    err = np.abs(rec.position_m[:, 2] - rec.ref_position_m[:, 2])
    assert m["bottom"].max_altitude_error_m == err.max() > 0.01
    assert m["bottom"].rms_altitude_error_m < m["bottom"].max_altitude_error_m
    assert m["top"].max_position_error_m == 0.0 and m["top"].max_authority_usage == 0.0
    np.testing.assert_allclose(
        m["bottom"].max_authority_usage, authority_usage(rec.vehicle, rec.applied_force_N, rec.applied_torque_Nm).max()
    )
    assert 0.0 < m["bottom"].max_motor_usage < 1.0
    assert m["bottom"].time_in_invalid_zone_s == 0.0  # 1.5 m > 3 L of a Crazyflie
    close = simulate_plan(hover_stack_plan(separation_m=0.2, duration_s=1.0), imu_noise=False, settle_s=0.0)
    assert simulation_metrics(close)["bottom"].time_in_invalid_zone_s > 0.9
    png = plot_errors(far, tmp_path / "e.png")
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_motor_usage_is_one_at_either_limit():
    v = BUILTIN_VEHICLES["large-quad"]
    thrusts = np.array(
        [
            [v.hover_thrust_per_rotor_N] * 4,
            [v.max_thrust_per_rotor_N] + [v.hover_thrust_per_rotor_N] * 3,
            [v.min_motor_thrust_N] + [v.hover_thrust_per_rotor_N] * 3,
        ]
    )
    np.testing.assert_allclose(motor_usage(v, thrusts), [0.0, 1.0, 1.0])


def test_wake_swirl_torque_shows_in_the_steady_motor_torques():
    """At steady hover (w = 0, w_dot = 0) S0-13 reduces to tau_a = -R tau_p: the motors cancel the
    applied yaw torque of the wake_swirl truth effect."""
    from proxplan.physics import mixer_matrix

    res = simulate_plan(
        hover_stack_plan(top_type="crazyflie-2.1", bottom_type="crazyflie-parrot", separation_m=1.0, duration_s=4.0),
        truth_effects=[Effect("wake_swirl", {"yaw_per_force_m": 0.05})],
        imu_noise=False,
        controller="rotorpy",  # steady hover: this swirl (4.8e-3 N m) is at the parrot's yaw authority, and the
        # firmware's motor cap gives up thrust for it (the Mellinger law does not reach a steady hover here)
    )
    rec = res.records["bottom"]
    late = rec.t_s > 3.0
    applied = rec.applied_torque_Nm[late].mean(axis=0)
    assert applied[2] < -1e-4
    tau_p = rec.motor_thrust_N[late] @ mixer_matrix(rec.vehicle)[1:].T  # body torques of the motors
    np.testing.assert_allclose(-tau_p.mean(axis=0)[2], applied[2], rtol=0.02)


def test_going_below_the_ground_is_noted_in_the_summary():
    from proxplan.flightsim import single_hover_plan, summary_dict

    res = simulate_plan(
        single_hover_plan(position_m=(0, 0, 0.02), duration_s=1.0),
        truth_effects=[Effect("thrust_bias", {"force_z_N": -0.05})],
        imu_noise=False,
    )
    notes = summary_dict(res)["notes"]
    ground = [n for n in notes if "below the ground plane" in n]
    assert len(ground) == 1 and "solo" in ground[0]
    # the bias the plan does not predict also pushes it out of its tube: said, not silent
    assert len(notes) == 2 and any("solo left its tube" in n for n in notes)
    ok = simulate_plan(single_hover_plan(position_m=(0, 0, 1.0), duration_s=1.0), imu_noise=False)
    assert summary_dict(ok)["notes"] == []
