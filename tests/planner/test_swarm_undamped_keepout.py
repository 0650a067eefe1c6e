"""The swarm layer's keep-outs hold the zones where a source's jet undamps the target's closed loop
(proxplan.planner.swarm.keepout.undamped_radius_m, issue 37 round 18A): right below a lighter source
the jet uses less authority than the cut-off but the verifier's loop there grows without bound, and
the swarm plans of pillar-128 and grid-256 parked or flew vehicles there and failed ``verify``."""

from __future__ import annotations

import numpy as np

from proxplan.physics import BUILTIN_VEHICLES
from proxplan.planfile import scenario_from_dict
from proxplan.planner.formations import grid_reshuffle
from proxplan.planner.swarm import swarm_problem
from proxplan.verify import hold_poles


def _scenario():
    return scenario_from_dict(grid_reshuffle(9, types=["crazyflie-2.1", "small-quad"]), label="test scenario")


def test_below_a_crazyflie_the_small_quad_is_undamped_and_kept_out():
    """The configuration of pillar-128's rejected plan (a small quad 0.5 m right below a Crazyflie):
    under the cut-off (the jet uses ~6 % of its authority, the cut-off is 10 %) but not damped by the
    verifier's test; the keep-out of the pair now holds it, at rest and moving."""
    scenario = _scenario()
    problem = swarm_problem(scenario, tracking_bound=False)
    cf, sq = BUILTIN_VEHICLES["crazyflie-2.1"], BUILTIN_VEHICLES["small-quad"]
    ia, ib = problem.vehicles.index(cf), problem.vehicles.index(sq)
    growth, _ = hold_poles(sq, np.zeros(3), [(cf, np.array([0.0, 0.0, 0.5]))], scenario.model_options, ())
    assert growth > 0.0  # the verifier's test: not damped there
    ko = problem.keepouts[(ia, ib)]  # d = p_b - p_a: the small quad below the Crazyflie
    d = np.array([[0.0, 0.0, -0.5], [0.03, 0.03, -0.45]])
    assert ko.conflict(d, rest=True).all()
    assert ko.conflict(d, rest=False).all()


def test_every_undamped_configuration_sampled_is_inside_the_keepout():
    """Random configurations below a source (azimuths 0 and 45 degrees, the ends of the sector the
    search covers; any dz, not on the table's rows; r within 0.3 m of the axis): every one where the
    verifier's hold test finds the target's loop not damped is in the pair's keep-out at rest."""
    scenario = _scenario()
    problem = swarm_problem(scenario, tracking_bound=False)
    rng = np.random.default_rng(7)
    n_undamped = 0
    for (ia, ib), ko in problem.keepouts.items():
        src, tgt = problem.vehicles[ia], problem.vehicles[ib]
        for _ in range(60):
            r, dz = rng.uniform(0.0, 0.3), rng.uniform(0.2, 1.0)
            phi = rng.choice([0.0, np.pi / 4])
            rel = np.array([r * np.cos(phi), r * np.sin(phi), -dz])  # target - source
            growth, _ = hold_poles(tgt, rel, [(src, np.zeros(3))], scenario.model_options, ())
            if growth >= 0.0:
                n_undamped += 1
                assert ko.conflict(rel[None, :], rest=True)[0], (src.name, tgt.name, r, dz, phi)
    assert n_undamped > 0  # the sample reaches the zones
