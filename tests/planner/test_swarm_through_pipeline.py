"""The swarm layer through the pipeline (proxplan.planner.plan_scenario, swarm_timed): plans pass the
verifier and are reproducible, the verifier catches a broken order, and the sampling planner beside
or after the swarm layer runs on a count budget."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from proxplan.planfile import scenario_from_dict
from proxplan.planner.formations import circle_swap, grid_reshuffle
from proxplan.planner.swarm import SwarmOptions, swarm_timed
from proxplan.planner.timing import assemble_plan
from proxplan.verify import verify_plan


def _plan(doc: dict, **options):
    sc = scenario_from_dict(doc, label="test scenario")
    timed, info = swarm_timed(sc, SwarmOptions(**options))
    return sc, assemble_plan(sc, timed, method="swarm", notes=[]), info


@pytest.mark.parametrize("layout", [grid_reshuffle, circle_swap])
def test_swarm_plans_pass_the_verifier_and_are_reproducible(layout):
    """Through the pipeline (its second pass grows each tube by the vehicle's predicted tracking error and
    jet response, issue 36; the swarm layer's first plan keeps the measured tubes only)."""
    from proxplan.planner import plan_scenario

    sc = scenario_from_dict(layout(8), label="test scenario")
    plan = plan_scenario(sc, method="swarm", seed=0)
    assert plan.verified and verify_plan(plan, sc) == []
    assert plan.metrics["makespan_s"] >= plan.metrics["lower_bound_s"] - 1e-9
    again = plan_scenario(sc, method="swarm", seed=0)
    assert again.metrics["makespan_s"] == plan.metrics["makespan_s"]
    for n, tr in plan.vehicles.items():
        np.testing.assert_array_equal(tr.position_m, again.vehicles[n].position_m)


def test_verify_rejects_a_plan_whose_timing_breaks_the_order():
    """Two vehicles trade sides through a gap in a wall that only one can pass at a time: the plan
    makes one wait for the other. Flying the waiting vehicle's path without its wait (the same
    path, started together with the other) breaks the order the plan relies on, and the verifier
    rejects it."""
    doc = {
        "name": "gap",
        "workspace": {"min": [-2.0, -1.5, 0.0], "max": [2.0, 1.5, 3.0]},
        "obstacles": [
            {"min": [-0.1, -1.5, 0.0], "max": [0.1, -0.3, 3.0]},
            {"min": [-0.1, 0.3, 0.0], "max": [0.1, 1.5, 3.0]},
        ],
        "limits": {"authority_fraction": 0.1, "min_separation_m": 0.25},
        "vehicles": {
            "a": {"type": "crazyflie-2.1", "start": [-1.2, 0.0, 1.0], "goal": [1.2, 0.0, 1.0]},
            "b": {"type": "crazyflie-2.1", "start": [1.2, 0.0, 1.0], "goal": [-1.2, 0.0, 1.0]},
        },
    }
    sc, plan, info = _plan(doc)
    assert verify_plan(plan, sc) == []
    in_gap = {n: int(np.flatnonzero(np.abs(tr.position_m[:, 0]) < 0.1)[0]) for n, tr in plan.vehicles.items()}
    first, second = sorted(in_gap, key=lambda n: in_gap[n])
    k = in_gap[second] - in_gap[first]
    assert k > 0, "the two vehicles pass the gap one after the other"

    def delayed(x, by):  # hold the first sample for ``by`` steps, the last one after the end
        return np.concatenate([np.repeat(x[:1], by, axis=0), x, np.repeat(x[-1:], k - by, axis=0)])

    def zero_start(x, by):
        y = delayed(x, by)
        y[:by] = 0.0
        return y

    t = np.arange(plan.t_s.size + k) * plan.dt_s
    vehicles = {}
    for n, tr in plan.vehicles.items():
        by = k if n == first else 0  # the first one now enters the gap with the second
        vehicles[n] = replace(
            tr,
            t_s=t,
            position_m=delayed(tr.position_m, by),
            velocity_mps=zero_start(tr.velocity_mps, by),
            acceleration_mps2=zero_start(tr.acceleration_mps2, by),
        )
    broken = replace(plan, vehicles=vehicles)
    kinds = {v.kind for v in verify_plan(broken, sc)}
    assert kinds & {"separation", "authority", "authority-tube", "invalid-zone"}


def test_a_lattice_plan_in_lockstep_gives_way_to_a_shorter_verified_sampling_plan():
    """Where prioritised planning gives up, the swarm layer's answer is the lattice plan flown in
    lock-step; the pipeline also runs the sampling planner and keeps the shorter verified plan."""
    from proxplan.planner import plan_scenario
    from proxplan.planner.timing import moving_end_s

    scenario = scenario_from_dict(grid_reshuffle(16), label="test scenario")
    # straight to the lattice coordination, as when prioritised planning gives up (the stacked plan
    # beside it left out: tests/planner/test_swarm_stacked.py)
    plan = plan_scenario(scenario, method="swarm", seed=0, swarm_options=SwarmOptions(prioritized=False, levels=False))
    assert plan.metrics["swarm"]["stage"] == "lattice"
    lattice_s = plan.metrics["swarm"]["makespan_s"]
    assert verify_plan(plan, scenario) == []
    assert moving_end_s(plan) <= lattice_s + plan.dt_s + 1e-9  # the plan grid rounds up by < one step
    assert any("sampling planner" in n for n in plan.notes)  # tried, whichever was kept


def test_the_sampling_alternative_stops_once_it_cannot_be_shorter_and_the_swarm_plan_is_kept():
    """Beside a prioritised plan (circle-16) the pipeline's sampling alternative stops at its first
    vehicle arriving no earlier than the swarm plan's makespan; the swarm plan is returned, verified,
    the same for the same seed, and the alternative run to its end on the same count budget would
    indeed not have been shorter."""
    import re

    from proxplan.planner import plan_scenario
    from proxplan.planner.errors import InfeasibleError, PlanNotFound
    from proxplan.planner.pipeline import ALTERNATIVE_RRT_ITERATIONS, ALTERNATIVE_SEARCHES_PER_VEHICLE
    from proxplan.planner.sampling import SamplingOptions, sampling_plan
    from proxplan.planner.timing import moving_end_s

    scenario = scenario_from_dict(circle_swap(16), label="test scenario")
    plan = plan_scenario(scenario, method="swarm", seed=0)
    assert plan.method == "swarm" and plan.metrics["swarm"]["stage"] == "prioritised"
    mine = moving_end_s(plan)
    stop = [n for n in plan.notes if "could not be shorter" in n]
    assert len(stop) == 1
    arrives = float(re.search(r"arrives at ([0-9.]+) s", stop[0]).group(1))
    assert arrives >= mine - 0.005  # printed to 2 decimals
    assert verify_plan(plan, scenario) == []
    again = plan_scenario(scenario, method="swarm", seed=0)
    for name, tr in plan.vehicles.items():
        np.testing.assert_array_equal(tr.position_m, again.vehicles[name].position_m)
    budget = SamplingOptions(
        max_searches=ALTERNATIVE_SEARCHES_PER_VEHICLE * len(scenario.vehicles),
        max_iterations=ALTERNATIVE_RRT_ITERATIONS,
    )
    try:
        full = sampling_plan(scenario, mode="downwash", seed=0, options=budget, progress=None)
    except (InfeasibleError, PlanNotFound):
        return  # no plan at all within the budget: not shorter either
    assert moving_end_s(full) >= mine


def test_the_sampling_planner_after_the_swarm_layer_gave_up_runs_on_a_count_budget():
    """Where the swarm layer searched and gave up (here LaCAM on one configuration, prioritised planning
    off) the sampling planner plans within ALTERNATIVE_SEARCHES_PER_VEHICLE searches per vehicle of at
    most ALTERNATIVE_RRT_ITERATIONS (a smaller budget passed in is kept), says so, and its plan is
    verified."""
    from proxplan.planner import plan_scenario
    from proxplan.planner.pipeline import ALTERNATIVE_RRT_ITERATIONS, ALTERNATIVE_SEARCHES_PER_VEHICLE, _counted
    from proxplan.planner.sampling import SamplingOptions

    scenario = scenario_from_dict(
        circle_swap(4), label="test scenario"
    )  # every straight line crosses the centre: no straight plan
    plan = plan_scenario(scenario, method="swarm", seed=0, swarm_options=SwarmOptions(prioritized=False, max_nodes=1))
    assert plan.method == "sampling" and plan.verified and verify_plan(plan, scenario) == []
    cap = ALTERNATIVE_SEARCHES_PER_VEHICLE * 4
    said = f"count budget: {cap} single-vehicle searches of at most {ALTERNATIVE_RRT_ITERATIONS} RRT iterations"
    assert any("swarm layer: no plan found" in n and said in n for n in plan.notes)
    assert _counted(SamplingOptions(), 4).max_searches == cap
    assert _counted(SamplingOptions(max_searches=3, max_iterations=50), 4) == SamplingOptions(
        max_searches=3, max_iterations=50
    )
