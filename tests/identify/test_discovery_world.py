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
