"""Tests of the joint move of ``optimized`` for swarms (proxplan.planner.optimizer.joint_move)."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.planfile import scenario_from_dict
from proxplan.planner import plan_scenario
from proxplan.planner.formations import formation_change
from proxplan.planner.optimizer import JointOptions, default_wrench_provider, joint_moves, moving_end_s
from proxplan.planner.optimizer.joint_move import _Joint
from proxplan.planner.optimizer.reoptimize import arrival_s
from proxplan.planner.optimizer.warm_problem import table_extent
from proxplan.verify import verify_plan


@pytest.fixture(scope="module")
def formation_6():
    scenario = scenario_from_dict(formation_change(6), label="formation-6")
    return scenario, plan_scenario(scenario, method="sampling", seed=0)


def _moves(scenario, plan):
    return joint_moves(
        scenario,
        plan,
        wrench_provider=default_wrench_provider,
        extent_provider=table_extent,
        options=JointOptions(max_solves=1, max_rounds=1, fractions=(0.8,)),
    )


def test_joint_moves_keep_a_verified_plan_no_longer_and_repeat_exactly(formation_6):
    scenario, initial = formation_6
    result = _moves(scenario, initial)
    assert verify_plan(result.plan, scenario) == []
    assert moving_end_s(result.plan) <= moving_end_s(initial) + 1e-9  # never worse
    assert result.improved == (moving_end_s(result.plan) < moving_end_s(initial) - 1e-9)
    assert ("->" in result.message) == result.improved
    assert result.solves == 1  # the count budget
    for name, tr in result.plan.vehicles.items():
        np.testing.assert_allclose(tr.position_m[0], scenario.vehicles[name].start_m, atol=1e-6)
        np.testing.assert_allclose(tr.position_m[-1], scenario.vehicles[name].goal_m, atol=1e-3)
    again = _moves(scenario, initial)  # count budgets, no wall time: the same plan
    assert again.message == result.message
    for name, tr in result.plan.vehicles.items():
        np.testing.assert_array_equal(tr.position_m, again.plan.vehicles[name].position_m)


def test_a_joint_problem_moves_the_group_and_fixes_the_others_without_the_group_in_their_background(formation_6):
    scenario, initial = formation_6
    jm = _Joint(scenario, initial, JointOptions(), default_wrench_provider, table_extent)
    ro = jm.ro
    movers = sorted(initial.vehicles, key=lambda n: -arrival_s(initial.vehicles[n]))[:2]
    T = max(arrival_s(initial.vehicles[m]) for m in movers)
    pb = ro.problem(movers, T, None)
    assert sorted(a.name for a in pb.agents if a.moving) == sorted(movers)
    assert (movers[0], movers[1]) in pb.wrench_functions and (movers[1], movers[0]) in pb.wrench_functions
    for a in pb.agents:
        if a.moving:
            continue
        assert a.fixed_path_m is not None and a.background_wrench is not None
        # the disturbance from outside the problem: the total less both movers' contributions
        expect = ro.field.force[a.name][:, 2].copy()
        for m in movers:
            expect -= ro.field.current(m, a.name)[0][:, 2]
        got = ro.field.wrench_at(a.name, ro.field.t_s, without=movers)[0]
        np.testing.assert_allclose(got, expect, atol=1e-12)
