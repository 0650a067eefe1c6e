"""Conflict-driven re-ordering (proxplan.planner.sampling.ordering.promote) and the pre-checks of proxplan.planner.checks.precheck."""

from __future__ import annotations

import pytest

import proxplan.planner.sampling.prioritized as prioritized
from proxplan.fileio import UserError
from proxplan.planfile import scenario_from_dict
from proxplan.planner import InfeasibleError, PlanNotFound, plan_scenario
from proxplan.planner.sampling import SamplingOptions
from proxplan.planner.sampling.ordering import lower_bound_makespan_s, priority_order, promote
from proxplan.verify import verify_plan

FAST = SamplingOptions(max_iterations=1500, candidates=1)


def _junction():
    """A one-lane corridor along x with a one-lane branch along y joining it at x = 0.

    ``slow`` (the longer flight at 0.5 m/s, so planned first) passes the junction before ``branch``
    can reach it and parks at x = 1.2, where ``branch`` must pass to reach x = 1.6: in that order
    ``branch`` can never pass; the other way round ``branch`` passes first and ``slow`` waits."""
    return scenario_from_dict(
        {
            "name": "junction",
            "workspace": {"min": [-1.5, -0.15, 0.9], "max": [3.0, 3.0, 1.2]},
            "obstacles": [
                {"min": [-1.5, 0.15, 0.9], "max": [-0.15, 3.0, 1.2]},
                {"min": [0.15, 0.15, 0.9], "max": [3.0, 3.0, 1.2]},
            ],
            "limits": {"authority_fraction": 0.1, "min_separation_m": 0.25},
            "vehicles": {
                "slow": {
                    "type": "crazyflie-2.1",
                    "start": [-0.6, 0.0, 1.05],
                    "goal": [1.2, 0.0, 1.05],
                    "max_speed_mps": 0.5,
                },
                "branch": {"type": "crazyflie-2.1", "start": [0.0, 2.6, 1.05], "goal": [1.6, 0.0, 1.05]},
            },
        }
    )


def test_longest_flight_first_and_promotion_before_the_blocker():
    sc = _junction()
    assert priority_order(sc) == ["slow", "branch"]
    assert promote(sc, ["slow", "branch"], "branch", "separation from slow") == (["branch", "slow"], 0)
    assert lower_bound_makespan_s(sc) > 0


def test_reordering_solves_what_the_fixed_order_cannot(monkeypatch):
    sc = _junction()
    with monkeypatch.context() as m:
        m.setattr(prioritized, "MAX_REORDERS", 0)  # the fixed longest-first order
        with pytest.raises(PlanNotFound, match="gave up after 0 re-ordering") as err:  # not "infeasible": it is not
            plan_scenario(sc, method="sampling", options=FAST)
        assert err.value.vehicles == ["branch"] and err.value.details["reorderings"] == 0
    plan = plan_scenario(sc, method="sampling", options=FAST)
    assert plan.metrics["priority_order"] == ["branch", "slow"]
    assert any(n.startswith("re-ordering: branch failed") for n in plan.notes)
    assert verify_plan(plan, sc) == []


def _pair(a, b, **extra):
    return scenario_from_dict(
        {
            "name": "pair",
            "workspace": {"min": [-3, -3, 0], "max": [3, 3, 3]},
            "limits": {"authority_fraction": 0.1, "min_separation_m": 0.25},
            "vehicles": {
                "a": {"type": "crazyflie-2.1", "start": a, "goal": [2.0, 0.0, 1.0]},
                "b": {"type": "crazyflie-2.1", "start": b, "goal": [2.0, 1.0, 1.0], **extra},
            },
        }
    )


def test_starts_inside_each_others_cutoff_are_infeasible_before_any_search():
    with pytest.raises(InfeasibleError) as err:
        plan_scenario(_pair([0.0, 0.0, 1.0], [0.0, 0.0, 1.5]), method="sampling")  # b right above a
    assert err.value.vehicle == "a" and err.value.constraint == "downwash of b"
    assert "start" in err.value.message


def test_swarm_size_limit_is_a_user_error(monkeypatch):
    import proxplan.planner.checks.precheck as precheck

    monkeypatch.setattr(precheck, "MAX_VEHICLES", 1)
    with pytest.raises(UserError, match="expected at most 1 vehicles"):
        plan_scenario(_pair([0.0, 0.0, 1.0], [0.0, 1.0, 1.0]), method="sampling")
