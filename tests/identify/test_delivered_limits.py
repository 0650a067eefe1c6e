"""A log whose u[N] is DELIVERED keeps it at the motor limits (identify.thrust_map.delivered_log_limits).

On a commanded log a u[N] past a limit is a desired force the motor does not give, and the PWM map's force is put
there. A delivered u[N] (a simulator's k_eta omega^2) is the rotors' force: it disagrees with the PWM (a command) by
the motor lag and by the map's error where the map is an extrapolation, and replacing it put the unlagged,
extrapolated command in place of the measurement (docs/identify.md, stop 66)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from proxplan.identify.thrust_map import CEILING, FLOOR, IN_RANGE, MotorSamples, delivered_log_limits

MAX_N = 1.15  # the small quad's max thrust per rotor, N


def _samples(u: np.ndarray) -> MotorSamples:
    n = len(u)
    return MotorSamples(commanded_N=np.repeat(u[:, None], 4, axis=1), pwm=np.full((n, 4), 0.5), vbat_V=np.full(n, 4.0))


def test_a_delivered_force_inside_the_motor_range_is_never_a_limit() -> None:
    u = np.concatenate([np.linspace(0.3, MAX_N, 50), np.linspace(MAX_N, 0.0, 50)])  # up to both ends, never past
    limits = np.zeros((100, 4), dtype=np.int8)
    limits[30:60] = CEILING  # what motor_limits flags where the map's ends are off
    limits[90:] = FLOOR
    out = delivered_log_limits(limits, _samples(u), min_thrust_N=0.0, max_thrust_N=MAX_N)
    assert np.all(out == IN_RANGE)


def test_a_desired_force_in_a_delivered_log_is_still_a_limit() -> None:
    """A mis-declared log: u[N] past the motor's maximum or below zero is a desired force; its whole flagged
    stretch stays at the limit, and a flagged stretch that never leaves the range does not."""
    u = np.full(100, 0.5)
    u[20:30] = np.linspace(1.0, 1.6, 10)  # runs past 1.15 N * (1 + 2 %)
    u[60:70] = np.linspace(0.2, -0.3, 10)  # negative: the motor off, the controller asking for less
    limits = np.zeros((100, 4), dtype=np.int8)
    limits[18:32] = CEILING
    limits[58:72] = FLOOR
    limits[80:90] = CEILING  # flagged, but u stays at 0.5 N
    out = delivered_log_limits(limits, _samples(u), min_thrust_N=0.0, max_thrust_N=MAX_N)
    assert np.all(out[18:32] == CEILING) and np.all(out[58:72] == FLOOR)
    assert np.all(out[80:90] == IN_RANGE) and np.all(out[:18] == IN_RANGE)


@pytest.mark.slow
def test_saturating_simulator_flight_is_measured_from_its_delivered_thrust(tmp_path: Path) -> None:
    """Two small quads swapping 0.3 m apart with a hidden yaw torque of 0.05 m x F_z (the library-alone check's
    wake_swirl), the thrust map fitted beside a clean flight: the bottom quad's motors hit both ends. Its measured
    F_z follows the force the simulator applied, up to RotorPy's own rotor inflow and the noise: 1.03 g RMS; with
    the commanded-log rule (u[N] replaced wherever motor_limits flags it) 8.06 g (stop 66)."""
    import yaml

    from proxplan.flightsim import simulate_plan, write_flight_logs
    from proxplan.flightsim.identify_flights import HIDDEN_EFFECTS
    from proxplan.flightsim.scenarios_synthetic import swap_plan
    from proxplan.identify import IdentifyOptions
    from proxplan.identify.loading import load_units
    from proxplan.identify.manifest import load_manifest

    for k, (gap_m, effects) in enumerate([(0.6, []), (0.3, [HIDDEN_EFFECTS["wake_swirl"]])]):
        plan = swap_plan(top_type="small-quad", bottom_type="small-quad", vertical_gap_m=gap_m, cross_offset_m=0.03,
                         centre_m=(0.0, 0.0, 1.0 + 0.4 * (1 - k)), n_swaps=2, swap_s=2.5)  # fmt: skip
        flown = simulate_plan(plan, truth_effects=effects, seed=2000 + 1 - k)
        manifest = write_flight_logs(flown, tmp_path, flight_name=f"f{1 - k}", split="train")
    assert yaml.safe_load(manifest.read_text())["motor_thrust"] == "delivered"
    data = load_units(load_manifest(manifest, require_train_and_test=False), options=IdentifyOptions(progress=False))
    (bottom,) = [u for u in data.units if u.name == "bottom" and u.flight == "f0"]
    assert data.exclusions["f0"]["bottom"]["thrust_source"] == "pwm"  # the map is usable: the limit rule applies
    import gzip

    with gzip.open(tmp_path / "f0" / "bottom_truth.csv.gz", "rt") as fh:
        header = fh.readline().lstrip("# ").strip().split(",")
        truth = np.loadtxt(fh, delimiter=",", ndmin=2)
    applied = np.interp(bottom.t_s, truth[:, header.index("t_s")], truth[:, header.index("fz_applied_N")])
    off_g = np.sqrt(np.mean((bottom.force_N[:, 2] - applied) ** 2)) * 1000.0 / 9.80665
    print(f"bottom F_z off the applied force: {off_g:.2f} g RMS")
    assert off_g < 2.5, off_g
