"""The shipped hand-off's receiver, a small quad holding 1.1 m under a large quad's jet, flown:
the model before issue 36 (the static sag F / k_p and its transient, of the reduced position loop
m d'' + (k_d + c m) d' + k_p d + k_i int(d) = F + m g (tau_y, -tau_x) / k_R; restated here as the
reference it was, commit d30c71c proxplan.physics.disturbance_deflection) puts it beyond its tube;
the closed loop in the jet (the jet's force and torque gradients fed back through the attitude
loop's lag, proxplan.verify.predicted_tube_growth) predicts what it flies."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from proxplan.flightsim import SimulationOptions, simulate_plan
from proxplan.flightsim.report import predicted_deflection_m, record_tube_m
from proxplan.planfile import load_scenario
from proxplan.planner import plan_scenario
from proxplan.verify import scenario_of_plan, verify_plan, wrench_along_plan

SCENARIOS = Path(__file__).resolve().parents[2] / "scenarios"
HOLD_S = 6.0  # flown after the plan's end: the lightly damped lateral mode rings (0.8 Hz, ~5 s to e-fold)


def test_the_receiver_leaves_the_force_only_prediction_and_stays_in_the_closed_loop_one():
    scenario = load_scenario(SCENARIOS / "handoff.yaml")
    plan = plan_scenario(scenario, method="sampling", seed=0)
    assert verify_plan(plan, scenario) == []
    flown = simulate_plan(plan, options=SimulationOptions(imu_noise=False, settle_s=HOLD_S)).records["receiver"]
    err = np.linalg.norm(flown.position_m - flown.ref_position_m, axis=1)
    tube = record_tube_m(flown)

    # the closed-loop prediction (what verify grants): the flight stays within tube + it
    closed = predicted_deflection_m(flown)
    assert np.all(err <= tube + closed), float(np.max(err - tube - closed))

    # the model before issue 36, on the same wrench along the plan, held after the end
    sc = scenario_of_plan(plan)
    w = wrench_along_plan(plan, sc, t_s=flown.t_s)["receiver"]  # (the plan's last values after its end)
    before = np.linalg.norm(_sag_model(flown.t_s, w.force_N, w.torque_Nm, sc.vehicles["receiver"].vehicle), axis=1)
    beyond = float(np.max(err - tube - before))
    assert beyond > 0.01, beyond  # over 1 cm beyond its tube: the oscillation the sag does not model


def _sag_model(t_s, force_N, torque_Nm, vehicle):
    """The deflection (K, 3), m, of the model before issue 36 (module docstring), from rest."""
    from scipy import signal

    g = vehicle.controller
    m = vehicle.mass_kg
    drive = np.asarray(force_N, dtype=float).copy()
    per = m * 9.81 / g.kR_xy_Nmprad
    drive[:, 0] += per * torque_Nm[:, 1]
    drive[:, 1] -= per * torque_Nm[:, 0]
    out = np.zeros_like(drive)
    for k in range(3):
        c = vehicle.drag_rate_ps[k] * m
        # states (int d, d, d'): m d'' = F - (k_d + c) d' - k_p d - k_i int d
        a = np.array([[0, 1, 0], [0, 0, 1], [-g.ki_Npms[k] / m, -g.kp_Npm[k] / m, -(g.kd_Nspm[k] + c) / m]])
        sys_k = signal.StateSpace(a, [[0], [0], [1 / m]], [[0, 1, 0]], [[0]])
        out[:, k] = signal.lsim(sys_k, drive[:, k], t_s, interp=True)[1]
    return out
