"""Round 37Z (issue 37): a goal the verifier can pass is plannable. Two large quads change formation, b's goal
``DZ_M`` above a's and to the side of it by an amount between the reaches of b's cut-off on a (the planners' rule,
``build_checker``, so no figure here is tuned): at rest, grown by the tracking tube (the verifier's rule while either
moves) and grown by the tube and the sampling planner's search margin.

- between the tube's reach and the margin's: planned, by the sampling planner and by the swarm layer, and the
  verifier passes the plan (before round 37Z the pipeline rejected it before any search, "goal-in-tube");
- between the reach at rest and the tube's: rejected before any search, naming the pair, the distance and what
  the pair needs (the verifier rejects every plan: the later of the two arrives moving);
- inside the reach at rest: a user mistake, named as before.
"""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.fileio import UserError
from proxplan.planfile import scenario_from_dict
from proxplan.planner import InfeasibleError, plan_scenario
from proxplan.planner.checks.constraints import Track, build_checker
from proxplan.planner.checks.precheck import check_goal_tubes, check_starts_and_goals
from proxplan.planner.sampling import PLAN_MARGIN_M
from proxplan.planner.sampling.prioritized import margin_free
from proxplan.planner.swarm.problem import GROWTH_M, swarm_problem
from proxplan.verify import verify_plan

DZ_M = 0.7  # b's goal above a's, m


def _doc(lateral_m: float) -> dict:
    """Two large quads change formation: b's goal ``lateral_m`` (m) to the side of a's and ``DZ_M`` above."""
    return {
        "name": "goal-in-margin",
        "workspace": {"min": [-3, -3, 0], "max": [3, 3, 3]},
        "limits": {"authority_fraction": 0.1, "min_separation_m": 0.25, "tracking_margin_m": 0.0139},
        "vehicles": {
            "a": {"type": "large-quad", "start": [-1.5, -2.0, 1.0], "goal": [0.0, 1.0, 1.0]},
            "b": {"type": "large-quad", "start": [1.5, -2.0, 1.0 + DZ_M], "goal": [lateral_m, 1.0, 1.0 + DZ_M]},
        },
    }


def _reach_m(tube: bool, margin_m: float) -> float:
    """b's cut-off on a at DZ_M (the planner's rule), with or without the tube, plus ``margin_m``, m."""
    s = scenario_from_dict(_doc(2.0))
    b = Track.static("b", s.vehicles["b"].vehicle, np.array([0.0, 1.0, 1.0 + DZ_M]))
    rule = build_checker(s, "a", [b], mode="downwash", tube=tube, margin_m=margin_m).rules[0]
    return rule.cutoff_m(rule.cut_from_other, DZ_M)


def _in_margin_m() -> float:
    """Halfway between the reach with the tube alone and with the tube and the search margin, m."""
    return 0.5 * (_reach_m(True, 0.0) + _reach_m(True, PLAN_MARGIN_M))


def _in_tube_m() -> float:
    """Halfway between the reach at rest and with the tube, m."""
    return 0.5 * (_reach_m(False, 0.0) + _reach_m(True, 0.0))


def test_a_goal_inside_the_search_margin_only_passes_the_checks_before_any_search():
    scenario = scenario_from_dict(_doc(_in_margin_m()))
    check_starts_and_goals(scenario, mode="downwash")
    check_goal_tubes(scenario, mode="downwash")  # the verifier's rule: no error
    # the sampling planner searches this pair without its margin, and only this pair's goal is concerned
    assert margin_free(scenario, "a", mode="downwash") == {"b"}
    assert margin_free(scenario, "b", mode="downwash") == {"a"}
    assert margin_free(scenario_from_dict(_doc(_reach_m(True, PLAN_MARGIN_M) + 0.01)), "a", mode="downwash") == set()


def test_the_swarm_keepout_at_rest_is_the_verifiers_rule_grown_by_the_held_bound():
    """The pair's keep-out while both rest: the cut-off without the tube, grown by the two vehicles' tracking
    error while held (< the bound while moving), so the goal pair is clear of it at rest; moving it is not."""
    x = _in_margin_m()
    problem = swarm_problem(scenario_from_dict(_doc(x)))
    ko = problem.keepouts[(0, 0)]
    rel = np.array([[x, 0.0, DZ_M]])  # b's goal from a's
    assert not ko.conflict(rel, rest=True)[0] and ko.conflict(rel)[0]
    assert ko.w_rest_m < ko.deflection_m  # held vs moving growth of the pair, m
    assert ko.w_move_m == pytest.approx(0.0139 + GROWTH_M + ko.deflection_m)


@pytest.mark.parametrize("method", ["sampling", "swarm"])
def test_a_goal_inside_the_search_margin_only_is_planned_and_verified(method):
    scenario = scenario_from_dict(_doc(_in_margin_m()))
    plan = plan_scenario(scenario, method=method, seed=0)
    assert verify_plan(plan, scenario) == []
    for name in ("a", "b"):
        end = plan.vehicles[name].position_m[-1]
        assert np.allclose(end, scenario.vehicles[name].goal_m, atol=1e-6)


def test_a_goal_inside_the_tube_is_rejected_before_any_search_naming_the_pair():
    x = _in_tube_m()
    scenario = scenario_from_dict(_doc(x))
    check_starts_and_goals(scenario, mode="downwash")  # clear at rest
    with pytest.raises(InfeasibleError) as info:
        check_goal_tubes(scenario, mode="downwash")
    d = info.value.details
    assert d["kind"] == "goal-in-tube" and d["vehicle"] == "a" and d["other_vehicle"] == "b"
    assert d["distance_is_lateral"] and d["distance_m"] == pytest.approx(x, abs=1e-6)
    assert d["dz_m"] == pytest.approx(DZ_M, abs=1e-9)
    assert d["needed_m"] == pytest.approx(_reach_m(True, 0.0), abs=1e-6)
    assert d["needed_at_rest_m"] == pytest.approx(_reach_m(False, 0.0), abs=1e-6)
    assert d["needed_at_rest_m"] < d["distance_m"] < d["needed_m"]
    msg = info.value.message
    assert f"{x:.3f} m to the side of b's final position, {DZ_M:.3f} m below it" in msg
    assert f"the pair needs {d['needed_m']:.3f} m ({d['needed_at_rest_m']:.3f} m at rest)" in msg
    assert "\n" not in msg
    for method in ("swarm", "sampling"):
        with pytest.raises(InfeasibleError) as again:
            plan_scenario(scenario, method=method, seed=0)
        assert again.value.details["kind"] == "goal-in-tube"


def test_a_goal_inside_the_cutoff_at_rest_is_a_user_mistake():
    scenario = scenario_from_dict(_doc(_reach_m(False, 0.0) - 0.01))
    with pytest.raises(UserError, match=r"vehicles\.a\.goal is inside the downwash cut-off of vehicles\.b\.goal"):
        plan_scenario(scenario, method="swarm", seed=0)
