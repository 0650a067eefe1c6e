"""Closed-loop simulation: hover, steady downwash disturbance seen in the synthetic logs (S0-11),
truth effects, the battery-swap approach comparison, wrench-horizon accuracy."""

from __future__ import annotations

import gzip
from pathlib import Path

import numpy as np
import pytest

from proxplan.flightsim import (
    hover_stack_plan,
    simulate_plan,
    single_hover_plan,
    swap_plan,
    waypoint_trajectory,
    write_flight_logs,
)
from proxplan.physics import BUILTIN_VEHICLES, Effect, disturbance_wrench
from proxplan.planfile import Plan

KP_Z = 15.0  # RotorPy SE3Control z position gain, 1/s^2 (no integral term: steady error = F / (m kp_z))
ROTORPY = "rotorpy"  # tests of a steady sag F / (m kp_z) fly RotorPy's PD law (the Mellinger law integrates it away)


def test_vehicle_hovering_alone_holds_position_within_a_few_centimetres():
    res = simulate_plan(single_hover_plan(type_name="crazyflie-2.1", position_m=(0.3, -0.2, 1.0), duration_s=3.0))
    rec = res.records["solo"]
    err = np.linalg.norm(rec.position_m - rec.ref_position_m, axis=1)
    assert err.max() < 0.02
    assert res.saturation_time_s["solo"] == 0.0
    # the IMU reads about +g on body z in hover
    np.testing.assert_allclose(rec.accel_meas_body_mps2[:, 2].mean(), 9.81, atol=0.02)


def _measured_force_s011(vehicle, table: np.ndarray) -> np.ndarray:
    """(S0-11) f_a = m R alpha - sum(f_i) z_B on a Neural-Swarm table (proxplan.identify.measure)."""
    from proxplan.identify import MeasureOptions, measure_disturbance

    t = table[:, 0] * 1e-6
    return measure_disturbance(
        vehicle, t, table[:, 10:14], table[:, 7:10], table[:, 14:18], table[:, 27:30], options=MeasureOptions()
    ).force_N


def _read_gz(path: Path) -> tuple[str, np.ndarray]:
    with gzip.open(path, "rt") as fh:
        header = fh.readline().strip()
    return header, np.loadtxt(path, delimiter=",", skiprows=1)


def test_vehicle_below_another_shows_predicted_steady_disturbance_in_its_log(tmp_path):
    plan = hover_stack_plan(top_type="crazyflie-2.1", bottom_type="crazyflie-parrot", separation_m=1.5, duration_s=4.0)
    res = simulate_plan(plan, seed=3, controller=ROTORPY)
    manifest = write_flight_logs(res, tmp_path, flight_name="stack", split="train")
    header, table = _read_gz(manifest.parent / "stack" / "bottom.csv.gz")
    assert header.startswith("# time[ms],x[m]")
    bottom = BUILTIN_VEHICLES["crazyflie-parrot"]
    top = BUILTIN_VEHICLES["crazyflie-2.1"]
    measured = _measured_force_s011(bottom, table)
    steady = table[:, 0] * 1e-6 > 1.5  # after the initial transient
    f_meas = measured[steady].mean(axis=0)
    # the model's prediction at the separation flown (and what was applied)
    rec = res.records["bottom"]
    offset = (rec.position_m - res.records["top"].position_m)[rec.t_s > 1.5].mean(axis=0)
    assert 1.5 < -offset[2] < 1.6  # the bottom vehicle sags a few cm under the load
    predicted = disturbance_wrench(top, bottom, offset[None, :]).force_N[0]
    applied = rec.applied_force_N[rec.t_s > 1.5].mean(axis=0)
    np.testing.assert_allclose(applied, predicted, rtol=0.02, atol=1e-4)
    n = int(steady.sum())
    noise_N = bottom.mass_kg * res.options.imu.accel_noise_std_mps2 / np.sqrt(n)  # std of the mean
    assert predicted[2] < -0.02  # a real, downward disturbance
    assert abs(f_meas[2] - predicted[2]) < 4 * noise_N + 0.01 * abs(predicted[2])
    assert np.all(np.abs(f_meas[:2]) < 4 * noise_N + 1e-3)
    # and the vehicle sags by F / (m kp_z) under it (RotorPy's SE3Control has no integral term)
    sag = (rec.position_m - rec.ref_position_m)[rec.t_s > 2.5, 2].mean()
    np.testing.assert_allclose(sag, predicted[2] / (bottom.mass_kg * KP_Z), rtol=0.03)
    # the top vehicle sees nothing
    assert np.all(res.records["top"].applied_force_N == 0.0)


def test_ground_effect_truth_lifts_a_low_hovering_vehicle():
    plan = single_hover_plan(type_name="crazyflie-2.1", position_m=(0.0, 0.0, 0.03), duration_s=3.0)
    res = simulate_plan(plan, truth_effects=[Effect("ground_effect", {"gain_k": 1.0})], controller=ROTORPY)
    rec = res.records["solo"]
    late = rec.t_s > 2.0
    lift = rec.applied_force_N[late, 2].mean()
    veh = BUILTIN_VEHICLES["crazyflie-2.1"]
    assert lift > 0.005 * veh.weight_N
    rise = (rec.position_m - rec.ref_position_m)[late, 2].mean()
    np.testing.assert_allclose(rise, lift / (veh.mass_kg * KP_Z), rtol=0.05)
    # without the truth effect the model sees nothing here
    plain = simulate_plan(plan).records["solo"]
    assert np.abs(plain.position_m - plain.ref_position_m).max() < 1e-6


def test_batched_wrench_horizon_matches_per_step_evaluation():
    plan = swap_plan(vertical_gap_m=0.5, swap_s=2.0, n_swaps=1, hold_s=0.5)
    exact = simulate_plan(plan, wrench_horizon_steps=1, imu_noise=False, settle_s=0.2)
    fast = simulate_plan(plan, imu_noise=False, settle_s=0.2)  # default horizon (10 steps)
    for name in exact.records:
        a, b = exact.records[name], fast.records[name]
        assert np.abs(a.applied_force_N).max() > 0.0 or name == "top"
        assert np.abs(a.position_m - b.position_m).max() < 5e-5
        assert np.abs(a.applied_force_N - b.applied_force_N).max() < 0.005 * np.abs(a.applied_force_N).max() + 1e-9


def _battery_swap(shuttle_path, times, duration_s):
    carrier = np.array([0.0, 0.0, 1.5])
    return Plan(
        "battery-swap-test",
        0.02,
        {
            "carrier": waypoint_trajectory("carrier", "large-quad", [carrier, carrier], [0.0, duration_s]),
            "shuttle": waypoint_trajectory("shuttle", "small-quad", shuttle_path, times),
        },
    )


def test_battery_swap_side_approach_disturbs_the_carrier_less_than_straight_line():
    """The shuttle docks 0.35 m above the hovering carrier, starting 1.8 m above it (slightly
    off-axis). The straight line descends through the carrier's axis at dz 1.8 -> 0.35 m, where the
    small-quad's downwash on the large frame peaks (about 0.7 N near dz = 1.6 m, against 0.41 N
    docked); a downwash-aware plan of the same duration moves aside first, descends beside the
    carrier and slides in at the dock height."""
    start = np.array([0.2, 0.1, 3.3])
    dock = np.array([0.0, 0.0, 1.85])
    T = 8.0
    straight = _battery_swap([start, dock], [0.0, T], T)
    staged = _battery_swap([start, [1.2, 0.6, 3.3], [1.2, 0.6, 1.85], dock], [0.0, 2.0, 5.0, T], T)
    errs, peak = {}, {}
    for name, plan in (("straight", straight), ("staged", staged)):
        rec = simulate_plan(plan, imu_noise=False, controller=ROTORPY).records["carrier"]
        errs[name] = np.abs(rec.position_m[:, 2] - rec.ref_position_m[:, 2]).max()
        peak[name] = np.abs(rec.applied_force_N[:, 2]).max()
    assert peak["staged"] < peak["straight"], peak
    assert errs["staged"] < 0.85 * errs["straight"], errs
    # both end docked: the final, steady sag is the same
    docked = disturbance_wrench(
        BUILTIN_VEHICLES["small-quad"], BUILTIN_VEHICLES["large-quad"], np.array([[0.0, 0.0, -0.35]])
    ).force_N[0, 2]
    assert errs["staged"] >= 0.9 * abs(docked) / (BUILTIN_VEHICLES["large-quad"].mass_kg * KP_Z)


def _fly_planned_battery_swap(tmp_path, method: str) -> float:
    """Plan scenarios/battery_swap.yaml with ``method`` in a fresh ``proxplan plan`` process (seed 0:
    the same sampling stage for every method) and return the carrier's max altitude error flown, m."""
    import subprocess
    import sys

    scenario = Path(__file__).resolve().parents[2] / "scenarios" / "battery_swap.yaml"
    out = tmp_path / method
    proc = subprocess.run(
        [sys.executable, "-m", "proxplan.cli", "plan", str(scenario), "--out", str(out), "--method", method,
         "--seed", "0", "--json", "--no-plot"],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    res = simulate_plan(out / "plan.json", imu_noise=False, controller=ROTORPY)
    docking = [n for n in res.records if n != "carrier"]
    assert "carrier" in res.records and docking
    rec = res.records["carrier"]
    return float(np.abs(rec.position_m[:, 2] - rec.ref_position_m[:, 2]).max())


@pytest.mark.parametrize("method", ["optimized"])
def test_planned_battery_swap_disturbs_the_carrier_less_than_no_downwash_baseline(tmp_path, method):
    """The optimised plan is flown with a smaller max altitude error of the docking vehicle's
    partner than the no-downwash baseline plan of the same scenario (each planned in a fresh
    process with seed 0). Not the sampling plan since issue 31: with the faster measured limits it
    docks early enough that its largest error is the docked sag, the same as the baseline's
    (4.08 / 4.07 cm; during the approach 3.4 / 3.6 cm)."""
    planned = _fly_planned_battery_swap(tmp_path, method)
    baseline = _fly_planned_battery_swap(tmp_path, "no-downwash")
    assert planned < baseline, (planned, baseline)


def test_integral_action_removes_the_steady_sag_below_another_vehicle():
    """With the seed's integral action (S0 IV-D) the steady error under a constant downwash decays;
    RotorPy's PD law keeps F / (m k_p)."""
    plan = hover_stack_plan(top_type="small-quad", bottom_type="large-quad", separation_m=1.5, duration_s=6.0)
    errors = {}
    for rate in (0.0, 1.0):
        res = simulate_plan(plan, imu_noise=False, position_integral_rate_ps=rate, controller=ROTORPY)
        rec = res.records["bottom"]
        errors[rate] = abs(float(rec.position_m[-1, 2] - rec.ref_position_m[-1, 2]))
    assert errors[1.0] < 0.2 * errors[0.0], errors


def test_grouped_wrench_equals_total_wrench_with_every_source():
    """The simulator's stacking of same-type sources, skipping of sources below the target and
    single evaluation of target-only effects give exactly proxplan.physics.effects.total_wrench."""
    from proxplan.flightsim.wrench import wrench_on as _wrench_for
    from proxplan.physics import EFFECT_NAMES, EffectInputs, ModelOptions, SourceSample, default_effect, total_wrench

    rng = np.random.default_rng(0)
    vehs = [
        BUILTIN_VEHICLES[n]
        for n in ("crazyflie-2.1", "crazyflie-parrot", "crazyflie-2.1", "crazyflie-parrot", "crazyflie-2.1")
    ]
    k = 6
    pos = np.zeros((k, 5, 3))
    pos[:, :, :2] = rng.normal(scale=0.15, size=(1, 5, 2)) + rng.normal(scale=0.01, size=(k, 5, 2))
    pos[:, :, 2] = np.array([0.5, 1.0, 1.6, 2.2, 0.3])[None, :] + 0.01 * np.arange(k)[:, None]
    vel = rng.normal(scale=0.3, size=(k, 3))
    effects = tuple(default_effect(n) for n in EFFECT_NAMES) + (Effect("wake_advection", {"wind_x_mps": 1.0}),)
    opts = ModelOptions()
    for i in range(5):
        f, t = _wrench_for(i, pos, vel, vehs, effects, opts, 0.0)
        inputs = EffectInputs(
            vehs[i],
            pos[:, i, 2],
            vel,
            tuple(SourceSample(vehs[j], pos[:, i] - pos[:, j]) for j in range(5) if j != i),
            opts,
        )
        f_ref, t_ref = total_wrench(inputs, effects)
        np.testing.assert_allclose(f, f_ref, rtol=1e-10, atol=1e-14)
        np.testing.assert_allclose(t, t_ref, rtol=1e-10, atol=1e-16)
    assert np.abs(_wrench_for(0, pos, vel, vehs, (), opts, 0.0)[0]).max() > 0.0  # the lowest one is hit


def test_a_delayed_truth_effect_is_applied_at_once_and_the_notes_say_so():
    """Each step's wrench is evaluated on that step's state (no history): a truth effect with lag_s acts at
    once, and the simulation's notes name it (never a silent difference from the logs' effect)."""
    plan = single_hover_plan(type_name="crazyflie-2.1", position_m=(0.0, 0.0, 1.0), duration_s=0.5)
    late = simulate_plan(plan, truth_effects=[Effect("ground_effect", {"gain_k": 1.0, "lag_s": 0.2})], settle_s=0.2)
    assert any("ground_effect" in n and "lag_s" in n for n in late.notes), late.notes
    assert not any("lag_s" in n for n in simulate_plan(plan, settle_s=0.2).notes)
