"""A residual force that depends on the flown state (``Perturbation.force_of_state``) is applied on the
vehicle's own states as it flies and recorded as applied beyond the model."""

from __future__ import annotations

import numpy as np

from proxplan.flightsim import Perturbation, simulate_plan, single_hover_plan

PUSH_N = 0.02  # N, world x, at the hover point
STIFFNESS_NPM = 0.1  # N/m: the push grows as the vehicle is carried along x (well below the position gain)


def _push(t_s, pos, vel, acc):
    out = np.zeros_like(pos)
    out[..., 0] = PUSH_N + STIFFNESS_NPM * pos[..., 0]
    return out


def test_the_force_follows_the_flown_state():
    plan = single_hover_plan(type_name="crazyflie-2.1", position_m=(0.0, 0.0, 1.0))
    rec = next(iter(simulate_plan(plan, perturbation=Perturbation(force_of_state=_push)).records.values()))
    applied = rec.applied_force_N - rec.model_force_N
    expected = PUSH_N + STIFFNESS_NPM * rec.position_m[:, 0]
    assert np.ptp(rec.position_m[:, 0]) > 0.005  # the push carries it: the state matters (m)
    assert np.max(np.abs(applied[:, 0] - expected)) < 0.05 * PUSH_N  # on its own states, within 5 %
    assert np.max(np.abs(applied[:, 1:])) == 0.0
