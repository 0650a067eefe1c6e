"""A residual wrench that depends on the flown state (``Perturbation.wrench_of_state``) is applied on the
vehicle's own states as it flies and recorded as applied beyond the model: its force and its torque."""

from __future__ import annotations

import numpy as np

from proxplan.flightsim import Perturbation, simulate_plan, single_hover_plan

PUSH_N = 0.02  # N, world x, at the hover point
STIFFNESS_NPM = 0.1  # N/m: the push grows as the vehicle is carried along x (well below the position gain)
ROLL_NM = 2e-4  # N m about world x, per m/s of the vehicle's x speed (a state-dependent torque)


def _push(t_s, pos, vel, acc):
    force_N, torque_Nm = np.zeros_like(pos), np.zeros_like(pos)
    force_N[..., 0] = PUSH_N + STIFFNESS_NPM * pos[..., 0]
    torque_Nm[..., 0] = ROLL_NM * (1.0 + vel[..., 0])
    return force_N, torque_Nm


def test_the_wrench_follows_the_flown_state():
    plan = single_hover_plan(type_name="crazyflie-2.1", position_m=(0.0, 0.0, 1.0))
    rec = next(iter(simulate_plan(plan, perturbation=Perturbation(wrench_of_state=_push)).records.values()))
    applied = rec.applied_force_N - rec.model_force_N
    expected = PUSH_N + STIFFNESS_NPM * rec.position_m[:, 0]
    assert np.ptp(rec.position_m[:, 0]) > 0.005  # the push carries it: the state matters (m)
    assert np.max(np.abs(applied[:, 0] - expected)) < 0.05 * PUSH_N  # on its own states, within 5 %
    assert np.max(np.abs(applied[:, 1:])) == 0.0
    torque = rec.applied_torque_Nm - rec.model_torque_Nm
    expected_torque = ROLL_NM * (1.0 + rec.velocity_mps[:, 0])
    assert np.ptp(rec.velocity_mps[:, 0]) > 0.01  # the speed the torque follows varies (m/s)
    assert np.max(np.abs(torque[:, 0] - expected_torque)) < 0.05 * ROLL_NM  # on its own states, within 5 %
    assert np.max(np.abs(torque[:, 1:])) == 0.0
    felt = np.mean(rec.cmd_moment_Nm[:, 0] + torque[:, 0])  # the dynamics felt it: the controller holds it (N m)
    assert abs(felt) < 0.2 * ROLL_NM  # measured 0.7 % of ROLL_NM
