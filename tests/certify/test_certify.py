"""Certification: deterministic draws, outcome probabilities that follow the vehicle, Wilson
intervals on known counts, the certify command's bad inputs and its local-cluster determinism."""

from __future__ import annotations

import json
import math
import time
from dataclasses import replace

import numpy as np
import pytest

from proxplan.certify import CertifySetup, NoiseSpec, Spreads, draw_run, fly_run, summarise_runs, wilson_interval
from proxplan.certify.draws import ou_series, run_rng
from proxplan.cli import main
from proxplan.flightsim import SimulationOptions, hover_stack_plan, simulate_plan, simulation_metrics
from proxplan.physics import BUILTIN_VEHICLES

Z95 = 1.959963984540054


def _wilson_by_hand(k: int, n: int) -> tuple[float, float]:
    p = k / n
    centre = (p + Z95**2 / (2 * n)) / (1 + Z95**2 / n)
    half = Z95 / (1 + Z95**2 / n) * math.sqrt(p * (1 - p) / n + Z95**2 / (4 * n * n))
    return max(0.0, centre - half), min(1.0, centre + half)


@pytest.mark.parametrize(("k", "n"), [(0, 10), (5, 10), (10, 10), (37, 200), (1, 1000)])
def test_wilson_interval_matches_the_closed_form(k, n):
    low, high = wilson_interval(k, n)
    ref_low, ref_high = _wilson_by_hand(k, n)
    assert low == pytest.approx(ref_low, abs=1e-9) and high == pytest.approx(ref_high, abs=1e-9)
    assert low <= k / n <= high


def test_wilson_interval_without_trials_is_uninformative():
    assert wilson_interval(0, 0) == (0.0, 1.0)


def _stack_types():
    plan = hover_stack_plan(separation_m=0.5, duration_s=1.0)
    return plan, {n: (t.type_name, t.vehicle) for n, t in plan.vehicles.items()}


def test_draws_depend_on_seed_and_run_index_only():
    _, types = _stack_types()
    a = draw_run(7, 3, types, 2.0)
    b = draw_run(7, 3, types, 2.0)
    c = draw_run(7, 4, types, 2.0)
    assert a.parameters == b.parameters and a.start_offset_m == b.start_offset_m
    assert np.array_equal(a.residual_force_N["bottom"].values, b.residual_force_N["bottom"].values)
    assert a.parameters != c.parameters
    # the run's stream is SeedSequence(seed).spawn(n)[index], whatever n is
    spawned = np.random.default_rng(np.random.SeedSequence(7).spawn(10)[3])
    assert spawned.standard_normal() == run_rng(7, 3).standard_normal()


def test_ou_process_has_the_requested_std_and_correlation_time():
    dt, tau = 0.01, 0.1
    x = ou_series(np.random.default_rng(0), 200_000, dt, tau, np.array([2.0]))[:, 0]
    assert np.std(x) == pytest.approx(2.0, rel=0.05)
    lag = int(round(tau / dt))
    rho = np.corrcoef(x[:-lag], x[lag:])[0, 1]
    assert rho == pytest.approx(math.exp(-1.0), abs=0.05)


def _setup(max_thrust_factor: float, *, seed: int = 0) -> CertifySetup:
    plan, _ = _stack_types()
    parrot = BUILTIN_VEHICLES["crazyflie-parrot"]
    flown = replace(parrot, max_thrust_N=max_thrust_factor * parrot.weight_N)
    return CertifySetup(
        plan=plan,
        seed=seed,
        authority_limit=0.5,
        min_separation_m=0.1,
        vehicles={"crazyflie-parrot": flown},
        options=SimulationOptions(imu_noise=False, settle_s=0.5),
    )


def test_a_too_weak_target_exceeds_authority_and_a_strong_one_does_not():
    n = 6
    weak = summarise_runs(_setup(1.15), [fly_run(_setup(1.15), k) for k in range(n)], [])
    strong = summarise_runs(_setup(4.0), [fly_run(_setup(4.0), k) for k in range(n)], [])
    assert weak["p_authority_exceeded"] >= 0.8
    assert strong["p_authority_exceeded"] <= 0.2
    low, high = weak["ci95"]["authority_exceeded"]
    assert low <= weak["p_authority_exceeded"] <= high
    assert set(weak["per_vehicle"]) == {"top", "bottom"}
    assert weak["per_vehicle"]["bottom"]["p_authority_exceeded"] >= 0.8


def test_a_run_is_the_same_flown_twice():
    setup = _setup(4.0, seed=11)
    assert fly_run(setup, 2) == fly_run(setup, 2)


def test_draws_without_spread_fly_the_plain_simulation():
    quiet = NoiseSpec(
        residual_std_z_weight=0.0, residual_std_xy_weight=0.0, estimate_std_m=0.0,
        estimate_std_mps=0.0, start_std_m=0.0, timing_std_s=0.0,
    )  # fmt: skip
    setup = replace(_setup(4.0), noise=quiet, spreads=Spreads({"c_ax": 0.0, "z0_m": 0.0, "c_rad": 0.0, "b_v": 0.0}))
    run = fly_run(setup, 0)
    plain = simulate_plan(setup.plan, vehicles=setup.vehicles, options=setup.options)
    usage = max(m.max_authority_usage for m in simulation_metrics(plain).values())
    assert run["peak_authority_usage"] == pytest.approx(usage, rel=1e-6)
    noisy = fly_run(_setup(4.0), 0)
    assert noisy["peak_authority_usage"] != pytest.approx(usage, rel=1e-3)


def test_leaving_the_tube_is_an_outcome():
    """Flown as planned (no draws) the vehicles stay within tube + predicted growth; a residual
    force of 20 % of the weight pushes them out of it."""
    quiet = NoiseSpec(
        residual_std_z_weight=0.0, residual_std_xy_weight=0.0, estimate_std_m=0.0,
        estimate_std_mps=0.0, start_std_m=0.0, timing_std_s=0.0,
    )  # fmt: skip
    none = Spreads({"c_ax": 0.0, "z0_m": 0.0, "c_rad": 0.0, "b_v": 0.0})
    calm = fly_run(replace(_setup(4.0), noise=quiet, spreads=none), 0)
    assert calm["left_tube"] is False
    assert all(v["tube_excess_m"] <= 0.0 for v in calm["per_vehicle"].values())
    shoved = fly_run(replace(_setup(4.0), noise=replace(quiet, residual_std_z_weight=0.2), spreads=none), 0)
    assert shoved["left_tube"] is True


def _cli(capsys, *args) -> tuple[int, str, str]:
    """``proxplan ARGS`` in this process: (exit code, stdout, stderr)."""
    capsys.readouterr()
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


def test_certify_command_same_seed_same_json_with_one_and_two_workers(capsys, battery_swap_plan, tmp_path):
    docs = []
    for workers in (1, 2):
        out = tmp_path / f"w{workers}"
        code, stdout, err = _cli(capsys, "certify", battery_swap_plan, "--runs", 3, "--seed", 5,
                                 "--workers", workers, "--out", out, "--json")  # fmt: skip
        assert code == 0, err
        printed = json.loads(stdout)
        assert printed["execution"]["workers"] == workers and printed["execution"]["retried_runs"] == 0
        docs.append((out / "certify.json").read_bytes())
        assert (out / "authority_histogram.png").stat().st_size > 1000
        assert (out / f"worst_run_{printed['worst_runs'][0]['index']}.png").exists()
    assert docs[0] == docs[1]
    summary = json.loads(docs[0])
    assert summary["runs"] == 3 and len(summary["worst_runs"]) == 3
    for key in ("p_authority_exceeded", "p_separation_violated", "p_goal_missed", "p_left_tube"):
        assert 0.0 <= summary[key] <= 1.0
    assert summary["tracking_error_m"]["p50"] <= summary["tracking_error_m"]["max"]
    # re-fly the worst run with simulate: the same flight
    worst = summary["worst_runs"][0]
    code, stdout, err = _cli(capsys, "simulate", battery_swap_plan, "--certify-run", worst["index"], "--seed", 5,
                             "--out", tmp_path / "refly", "--json")  # fmt: skip
    assert code == 0, err
    refly = json.loads(stdout)
    assert refly["certify_run"]["peak_authority_usage"] == worst["peak_authority_usage"]
    assert max(v["max_authority_usage"] for v in refly["vehicles"].values()) == worst["peak_authority_usage"]


def test_zero_runs_and_a_model_without_uncertainty(capsys, battery_swap_plan, tmp_path, write_yaml):
    model = write_yaml({"vehicles": {"large-quad": {"base": "large-quad"}}, "model": {"field_form": "inverse-z"}})
    code, stdout, err = _cli(capsys, "certify", battery_swap_plan, "--runs", 0, "--model", model,
                             "--out", tmp_path / "c", "--json")  # fmt: skip
    assert code == 0, err
    doc = json.loads(stdout)
    assert doc["runs"] == 0 and doc["p_authority_exceeded"] is None
    assert doc["ci95"]["authority_exceeded"] == [0.0, 1.0]
    assert any("no 'uncertainty'" in n and "default" in n for n in doc["notes"])
    assert doc["draws"]["spreads"].startswith("documented defaults")


def test_model_uncertainty_is_used(capsys, battery_swap_plan, tmp_path, write_yaml):
    model = write_yaml({"vehicles": {"large-quad": {"base": "large-quad"}},
                        "model": {"uncertainty": {"large-quad.c_ax": 0.5, "c_rad": 2.0}}})  # fmt: skip
    code, stdout, err = _cli(capsys, "certify", battery_swap_plan, "--runs", 0, "--model", model,
                             "--out", tmp_path / "c", "--json")  # fmt: skip
    assert code == 0, err
    doc = json.loads(stdout)
    assert doc["draws"]["spreads"] == "model file"
    assert doc["draws"]["spreads_absolute"] == {"large-quad.c_ax": 0.5, "c_rad": 2.0}


def test_negative_runs_and_unreachable_scheduler_are_one_line_errors(capsys, battery_swap_plan, tmp_path):
    code, _, err = _cli(capsys, "certify", battery_swap_plan, "--runs", -1, "--out", tmp_path / "a")
    assert code == 2 and "--runs" in err and len(err.strip().splitlines()) == 1
    t0 = time.perf_counter()
    code, _, err = _cli(capsys, "certify", battery_swap_plan, "--runs", 2, "--scheduler", "tcp://127.0.0.1:9",
                        "--out", tmp_path / "b")  # fmt: skip
    assert time.perf_counter() - t0 < 20.0  # the 10 s connect timeout, with a margin
    assert code == 2, err
    assert "cannot reach a Dask scheduler" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "b").exists()


def test_effect_parameters_are_drawn_from_effect_spreads():
    from proxplan.certify.run import _drawn_effects
    from proxplan.flightsim import TruthSpec
    from proxplan.physics import Effect

    setup = replace(
        _setup(4.0),
        truth=TruthSpec(effects=(Effect("near_field", {"amplitude": 0.5}),)),
        effect_spreads={"near_field.amplitude": 0.2},
    )
    _, types = _stack_types()
    draws = [draw_run(setup.seed, k, types, 2.0) for k in range(4)]
    amps = [_drawn_effects(setup, d)[0].full_params()["amplitude"] for d in draws]
    assert len(set(amps)) == 4 and all(abs(a - 0.5) < 5 * 0.2 for a in amps)
    assert _drawn_effects(setup, draws[0])[0].full_params() == _drawn_effects(setup, draws[0])[0].full_params()
    assert _drawn_effects(setup, draws[0])[0].full_params()["decay_L"] == 3.0  # no spread given: unchanged
