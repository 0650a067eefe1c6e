"""The discovery benchmark's world never asks for an effect the vehicles could not fly
(benchmarks/discovery_world.flyable_amplitude; docs/identify.md, "Stop 60 (lead)")."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import discovery_world as world  # noqa: E402

from proxplan.physics import mixer_matrix  # noqa: E402


def _motor_range(spec: world.SetSpec, amplitude: float) -> tuple[float, float]:
    """The largest excess over the top (N) and below the floor (N) of any motor at hover against the effect."""
    over, under = -np.inf, -np.inf
    for k in range(spec.n_train + 1):
        for inputs in world.flight_inputs(spec, k).values():
            veh = inputs.target
            f, tq = world.hidden_wrench(spec.effect, inputs)
            demand = np.column_stack([veh.weight_N - amplitude * f[:, 2], -amplitude * tq])
            u = np.linalg.solve(mixer_matrix(veh), demand.T).T
            over = max(over, float(np.max(u - veh.max_thrust_N / veh.n_rotors)))
            under = max(under, float(np.max(veh.min_motor_thrust_N - u)))
    return over, under


def test_the_amplitude_is_capped_exactly_at_what_the_motors_hold() -> None:
    spec = world.draw_spec(19001, "kernel")  # a Gaussian tail on the test flight: 2358 asked, 458x the weight
    cap = world.flyable_amplitude(spec)
    assert 0.0 < cap < 100.0
    over, under = _motor_range(spec, cap)
    assert abs(max(over, under)) < 1e-9  # one motor exactly at its limit (N), none beyond
    over, under = _motor_range(spec, 1.05 * cap)
    assert max(over, under) > 1e-3  # past it, a motor cannot give what the effect asks


def test_an_effect_well_inside_the_motors_is_not_capped() -> None:
    spec = world.draw_spec(19003, "thrust")  # a thrust loss near the ground of 2.2 % (amplitude 0.0219)
    assert world.flyable_amplitude(spec) > 1.0


def test_the_closed_loop_world_flies_the_effect_on_its_own_states(tmp_path: Path) -> None:
    """The flown world (``--world closed-loop``): the effect applied in flight is the hidden force on the vehicles'
    recorded states, and the logs' measured F_z carries it: effect set minus clean twin, same noise."""
    from dataclasses import replace

    from proxplan.identify import load_manifest, measure_log
    from proxplan.identify.vehicle_log import read_log
    from proxplan.physics import BUILTIN_VEHICLES

    spec = world.draw_spec(80002, "velocity")  # a force growing with |v_xy| on three vehicles
    spec = replace(spec, effect=world.closed_loop_effect(spec.effect), n_train=1, duration_s=6.0)
    clean, flown = world.make_set_closed_loop(spec, tmp_path / "clean", None)
    assert flown["flyable"] and len(flown["redraws"]) == 2
    amplitude = 0.05  # 5 % of each vehicle's weight per m/s of horizontal speed
    spec = replace(spec, redraws=tuple(flown["redraws"]))  # the effect set flies the clean set's motions
    effect, info = world.make_set_closed_loop(spec, tmp_path / "effect", amplitude)
    assert info["applied_mismatch"] < 0.01  # the force applied in flight is the effect on the recorded states
    ratios = []
    for fc, fe in zip(load_manifest(clean).flights, load_manifest(effect).flights, strict=True):
        for vc, ve in zip(fc.vehicles, fe.vehicles, strict=True):
            veh = BUILTIN_VEHICLES[spec.types[vc.name]]
            measured = (
                measure_log(veh, read_log(ve.log)).force_N[:, 2] - measure_log(veh, read_log(vc.log)).force_N[:, 2]
            )
            truth = np.loadtxt(ve.log.parent / f"{ve.name}_truth.csv.gz", delimiter=",", skiprows=1)
            applied = truth[:, 3] - truth[:, 9]  # F_z applied minus the base model's, N
            n = min(len(measured), len(applied))
            ratios.append(np.sqrt(np.mean((measured[:n] - applied[:n]) ** 2)) / np.sqrt(np.mean(applied[:n] ** 2)))
    assert max(ratios) < 0.3  # measured 0.008-0.105 (smoothing at the ends, motor lag)
