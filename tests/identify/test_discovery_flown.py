"""The discovery benchmark's FLOWN world (benchmarks/discovery_flown.py, ``--world closed-loop``): the effect
is applied in flight on the vehicles' own states and reaches the logs."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import discovery_flown as flown_world  # noqa: E402
import discovery_world as world  # noqa: E402


def test_the_closed_loop_world_flies_the_effect_on_its_own_states(tmp_path: Path) -> None:
    """The flown world (``--world closed-loop``): the effect applied in flight is the hidden force on the vehicles'
    recorded states, and the logs' measured F_z carries it: effect set minus clean twin, same noise."""
    from dataclasses import replace

    from proxplan.identify import load_manifest, measure_log
    from proxplan.identify.vehicle_log import read_log
    from proxplan.physics import BUILTIN_VEHICLES

    spec = world.draw_spec(80002, "velocity")  # a force growing with |v_xy| on three vehicles
    spec = replace(spec, n_train=1, duration_s=6.0)
    clean, flown = flown_world.make_set_closed_loop(spec, tmp_path / "clean", None)
    assert flown["flyable"] and len(flown["redraws"]) == 2
    amplitude = 0.05  # 5 % of each vehicle's weight per m/s of horizontal speed
    spec = replace(spec, redraws=tuple(flown["redraws"]))  # the effect set flies the clean set's motions
    effect, info = flown_world.make_set_closed_loop(spec, tmp_path / "effect", amplitude)
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


def test_an_effect_with_a_torque_is_flown_with_it(tmp_path: Path) -> None:
    """A thrust change per rotor carries a torque (S0-7, S0-8): the flown world applies the effect's whole wrench,
    so the torque applied in flight is the effect's torque on the recorded states, as the force is."""
    from dataclasses import replace

    spec = world.draw_spec(84000, "lag")  # thrust_quadratic 0.27 s late on three crazyflie-parrots
    assert spec.effect["inner"] == "thrust_quadratic"
    spec = replace(spec, n_train=1, duration_s=6.0)
    _, flown = flown_world.make_set_closed_loop(spec, tmp_path / "clean", None)
    spec = replace(spec, redraws=tuple(flown["redraws"]))
    effect, info = flown_world.make_set_closed_loop(spec, tmp_path / "effect", 0.3)
    assert info["applied_mismatch"] < 0.01 and info["applied_torque_mismatch"] < 0.01  # measured 0.12 %, 0.15 %
    torques = []
    for flight in sorted((tmp_path / "effect").glob("f*")):
        for truth_file in flight.glob("v*_truth.csv.gz"):
            truth = np.loadtxt(truth_file, delimiter=",", skiprows=1)
            torques.append(np.sqrt(np.mean((truth[:, 4:7] - truth[:, 10:13]) ** 2)))  # applied beyond the model
    assert max(torques) > 1e-4  # N m: a torque was applied (measured 2-5e-4 N m on the vehicles under another)
