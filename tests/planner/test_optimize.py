"""Tests of proxplan.planner.optimizer: refine_plan on the pipeline's sampling plan, fall-back, infeasibility."""

from __future__ import annotations

import copy
import json
from pathlib import Path

import numpy as np
import pytest

from proxplan.planfile import load_scenario, scenario_from_dict
from proxplan.planner import (
    InfeasibleError,
    plan_scenario,
)
from proxplan.planner.optimizer import (
    RefineOptions,
    build_problem,
    check_final_configuration,
    moving_end_s,
    refine_plan,
)
from proxplan.planner.optimizer.warm_problem import approach_start_s
from proxplan.verify import verify_plan

SCENARIOS = Path(__file__).resolve().parents[2] / "scenarios"


@pytest.fixture(scope="module")
def battery_swap():
    scenario = load_scenario(SCENARIOS / "battery_swap.yaml")
    return scenario, plan_scenario(scenario, method="sampling", seed=0)


def test_refined_battery_swap_is_faster_verified_and_docked(battery_swap):
    scenario, initial = battery_swap
    result = refine_plan(scenario, initial)
    assert result.success, result.message
    plan = result.plan
    assert plan.method == "optimized"
    assert verify_plan(plan, scenario) == []
    assert moving_end_s(plan) < moving_end_s(initial)
    assert result.iterations > 0 and result.solve_time_s > 0.0
    # common uniform grid of the initial plan's step, start and dock reached at rest
    t = plan.t_s
    np.testing.assert_allclose(np.diff(t), plan.dt_s, atol=1e-9)
    shuttle, carrier = plan.vehicles["shuttle"], plan.vehicles["carrier"]
    np.testing.assert_allclose(shuttle.position_m[0], scenario.vehicles["shuttle"].start_m, atol=1e-6)
    dock = carrier.position_m[-1] + scenario.vehicles["shuttle"].dock_offset_m
    np.testing.assert_allclose(shuttle.position_m[-1], dock, atol=1e-3)
    assert np.linalg.norm(shuttle.velocity_mps[-1]) < 1e-3
    np.testing.assert_allclose(carrier.position_m, np.tile(scenario.vehicles["carrier"].start_m, (t.size, 1)))
    assert any("CasADi/IPOPT" in note for note in plan.notes)


def test_problem_warm_start_and_bounds_come_from_the_initial_plan(battery_swap):
    scenario, initial = battery_swap
    problem = build_problem(scenario, initial, options=RefineOptions(interval_s=0.25, min_intervals=10))
    # the warm start is the sampling plan slowed by 1 / kinematic_margin (Ruckig flies at 100 % of
    # the limits, the OCP at 97 %), and T may not exceed that; is_better keeps the result faster
    slowed = moving_end_s(initial) / problem.kinematic_margin
    assert problem.max_duration_s == pytest.approx(slowed)
    assert problem.warm_times_s()[-1] == pytest.approx(slowed)
    assert problem.n_intervals == max(10, int(np.ceil(moving_end_s(initial) / 0.25)))
    # docking: the last intervals are the approach phase, which starts where the warm start enters
    # its final approach (on the A-D segment from then on)
    assert problem.approach_intervals >= 3
    t_a = approach_start_s(scenario, initial)
    assert problem.warm_times_s()[problem.n_intervals - problem.approach_intervals] == pytest.approx(
        t_a / problem.kinematic_margin
    )
    shuttle = next(a for a in problem.agents if a.name == "shuttle")
    carrier = next(a for a in problem.agents if a.name == "carrier")
    assert shuttle.moving and not carrier.moving
    np.testing.assert_allclose(shuttle.warm_position_m[0], initial.vehicles["shuttle"].position_m[0])
    np.testing.assert_allclose(shuttle.warm_position_m[-1], initial.vehicles["shuttle"].position_m[-1], atol=1e-9)
    assert shuttle.dock_reach_m > 0.0
    # both directions of the pair get a wrench function; a hovering pair would get none
    assert set(problem.wrench_functions) == {("carrier", "shuttle"), ("shuttle", "carrier")}


def test_failed_solve_falls_back_to_the_initial_plan(battery_swap):
    scenario, initial = battery_swap
    result = refine_plan(scenario, initial, options=RefineOptions(max_cpu_time_s=1e-3))
    assert not result.success
    assert result.plan is initial
    assert "kept the sampling plan" in result.message


def test_pipeline_optimized_method_uses_the_refinement(battery_swap):
    scenario, _ = battery_swap
    plan = plan_scenario(scenario, method="optimized", seed=0)
    assert plan.method == "optimized"
    assert plan.metrics["optimizer_iterations"] > 0
    assert verify_plan(plan, scenario) == []


def test_infeasible_authority_at_the_dock_is_reported_clearly():
    spec = copy.deepcopy(load_scenario(SCENARIOS / "battery_swap.yaml").spec)
    spec["limits"]["authority_fraction"] = 0.001
    scenario = scenario_from_dict(spec)
    with pytest.raises(InfeasibleError) as info:
        check_final_configuration(scenario)
    assert info.value.vehicle == "carrier"
    assert info.value.constraint == "authority"
    assert "shuttle" in info.value.message and "0.001" in info.value.message
    # a feasible limit passes the same check
    spec["limits"]["authority_fraction"] = 0.15
    check_final_configuration(scenario_from_dict(spec))


def test_rewarm_and_extent_pruning(battery_swap):
    from proxplan.planner.optimizer.acceptance import rewarm
    from proxplan.planner.optimizer.ocp import build_and_solve

    scenario, initial = battery_swap
    full = build_problem(scenario, initial)
    pruned = build_problem(scenario, initial, options=RefineOptions(prune_by_table_extent=True))
    assert not full.interaction_extent
    assert set(pruned.interaction_extent) == set(pruned.wrench_functions)
    # the extent widens with depth below the source (the jet spreads, S0-2)
    width = pruned.interaction_extent[("shuttle", "carrier")]
    assert width(2.0) > width(0.5) > 0.0
    sol = build_and_solve(full)
    assert sol.success, sol.status
    again = rewarm(full, sol)
    assert again.warm_duration_s == pytest.approx(sol.duration_s)
    shuttle = next(a for a in again.agents if a.name == "shuttle")
    np.testing.assert_allclose(shuttle.warm_position_m, sol.position_m["shuttle"])
    resolved = build_and_solve(again)  # a new local problem (sides, dock approach from the new warm start)
    assert resolved.success, resolved.status
    assert resolved.duration_s <= full.max_duration_s + 1e-6


def test_stop_when_verified_ends_after_a_verified_round(battery_swap):
    scenario, initial = battery_swap
    quick = refine_plan(scenario, initial, options=RefineOptions(stop_when_verified=True))
    full = refine_plan(scenario, initial)
    assert quick.success and full.success
    assert verify_plan(quick.plan, scenario) == []
    assert quick.iterations <= full.iterations
    assert moving_end_s(quick.plan) <= moving_end_s(initial)


def test_ipopt_statistics_travel_in_plan_json_and_json_output(battery_swap, tmp_path, capsys):
    from proxplan.cli import main
    from proxplan.planfile import read_plan

    assert (
        main(["plan", str(SCENARIOS / "battery_swap.yaml"), "--out", str(tmp_path / "p"), "--json", "--no-plot"]) == 0
    )
    doc = json.loads(capsys.readouterr().out)
    assert doc["method"] == "optimized"
    stats = doc["solver"]
    assert stats["converged"] is True and stats["return_status"] in ("Solve_Succeeded", "Solved_To_Acceptable_Level")
    assert stats["iterations"] > 0 and stats["solves"] >= 1 and stats["solve_time_s"] > 0.0
    assert 0.0 <= stats["constraint_violation"] < 1e-4
    plan = read_plan(tmp_path / "p")
    assert plan.solver is not None and plan.solver.to_dict() == stats
    assert "IPOPT" in (tmp_path / "p" / "summary.txt").read_text()
