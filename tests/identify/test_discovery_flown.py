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
    spec = replace(spec, effect=flown_world.closed_loop_effect(spec.effect), n_train=1, duration_s=6.0)
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
