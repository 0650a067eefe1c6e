"""Round 37Y (issue 37): a goal clear of the other's keep-out grown by the tracking tube alone but not by the
tube and the planner's search margin. The CLI's pre-check names the pair, the distance and what is needed
(at rest, with the tube alone, with the margin), and the pipeline rejects it before any search."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.planfile import scenario_from_dict
from proxplan.planner import InfeasibleError, plan_scenario
from proxplan.planner.checks.constraints import Track, build_checker
from proxplan.planner.checks.precheck import check_goal_tubes, check_starts_and_goals
from proxplan.planner.sampling import PLAN_MARGIN_M

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


def test_the_error_names_the_pair_the_distance_and_what_is_needed():
    x = _in_margin_m()
    scenario = scenario_from_dict(_doc(x))
    check_starts_and_goals(scenario, mode="downwash")  # clear at rest
    check_goal_tubes(scenario, mode="downwash", margin_m=0.0)  # and of the keep-out grown by the tube alone
    with pytest.raises(InfeasibleError) as info:
        check_goal_tubes(scenario, mode="downwash", margin_m=PLAN_MARGIN_M)
    d = info.value.details
    assert d["kind"] == "goal-in-tube" and d["vehicle"] == "a" and d["other_vehicle"] == "b"
    assert d["distance_is_lateral"] and d["distance_m"] == pytest.approx(x, abs=1e-6)
    assert d["dz_m"] == pytest.approx(DZ_M, abs=1e-9)
    assert d["needed_m"] == pytest.approx(_reach_m(True, PLAN_MARGIN_M), abs=1e-6)
    assert d["needed_with_tube_m"] == pytest.approx(_reach_m(True, 0.0), abs=1e-6)
    assert d["needed_at_rest_m"] == pytest.approx(_reach_m(False, 0.0), abs=1e-6)
    assert d["needed_at_rest_m"] < d["needed_with_tube_m"] < d["distance_m"] < d["needed_m"]
    msg = info.value.message
    assert f"{x:.3f} m to the side of b's final position, {DZ_M:.3f} m below it" in msg
    assert f"the pair needs {d['needed_m']:.3f} m" in msg and "\n" not in msg


def test_the_pipeline_rejects_it_before_any_search():
    with pytest.raises(InfeasibleError) as info:
        plan_scenario(scenario_from_dict(_doc(_in_margin_m())), method="swarm", seed=0)
    assert info.value.details["kind"] == "goal-in-tube"
