"""Holding points (proxplan.planner.swarm.holding, round 21B): a vehicle whose start and goal both lie on
another's line leaves its start before the other passes, waits beside its line and reaches its goal
after the other has passed."""

from __future__ import annotations

import numpy as np

from proxplan.planfile import scenario_from_dict
from proxplan.planner.swarm import swarm_problem
from proxplan.planner.swarm.chain import time_chain
from proxplan.planner.swarm.holding import HOLDING_REACHES, MAX_HOLDING_POINTS, holding_points, plan_via_holding
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.priority_options import PriorityOptions
from proxplan.planner.timing import assemble_plan
from proxplan.verify import verify_plan

HORIZON = 1200
FAR, NEAR = 0, 1


def _in_line():
    """Two vehicles on one line at one height: ``far`` (6 m) flies through ``near``'s start and goal (2 m,
    in the middle of it); a 2.4 m wide free band round the line."""
    doc = {
        "name": "in-line",
        "workspace": {"min": [-4.0, -1.2, 0.0], "max": [4.0, 1.2, 3.0]},
        "limits": {"authority_fraction": 0.1, "min_separation_m": 0.25},
        "vehicles": {
            "far": {"type": "crazyflie-2.1", "start": [-3.0, 0.0, 1.5], "goal": [3.0, 0.0, 1.5]},
            "near": {"type": "crazyflie-2.1", "start": [-1.0, 0.0, 1.5], "goal": [1.0, 0.0, 1.5]},
        },
    }
    sc = scenario_from_dict(doc, label="test scenario")
    return sc, swarm_problem(sc)


def test_holding_points_lie_beside_the_line_in_free_space_shortest_detour_first():
    _, problem = _in_line()
    occ = Occupancy(problem, [], HORIZON)
    points = holding_points(occ, NEAR)
    assert 0 < len(points) <= MAX_HOLDING_POINTS
    s, g = problem.starts_m[NEAR], problem.goals_m[NEAR]
    detours = [float(np.linalg.norm(h - s) + np.linalg.norm(g - h)) for h in points]
    assert detours == sorted(detours)
    for h in points:
        assert problem.static_free(h[None])[0]
        # off the line (y = 0) by one of HOLDING_REACHES reaches of the widest keep-out, at the line's height
        assert np.isclose(HOLDING_REACHES, abs(h[1]) / problem.reach_xy_m).any()
        assert h[2] == s[2]


def test_a_vehicle_on_anothers_line_waits_aside_and_the_plan_verifies():
    """``far`` flies its straight line first; ``near`` cannot fly its own line against it (it would have
    to leave after far passes its start and arrive before far passes its goal, or be overtaken); through
    a holding point it leaves first, waits beside the line while far passes, and arrives after it. The
    two tracks do not conflict and the plan passes the verifier."""
    sc, problem = _in_line()
    empty = Occupancy(problem, [], HORIZON)
    far = time_chain(empty, FAR, np.array([problem.starts_m[FAR], problem.goals_m[FAR]]), through=False)
    assert far is not None
    occ = Occupancy(problem, [far.track], HORIZON)
    straight = time_chain(occ, NEAR, np.array([problem.starts_m[NEAR], problem.goals_m[NEAR]]), through=False)
    assert straight is None
    near = plan_via_holding(occ, NEAR, through=False)
    assert near is not None
    assert occ.conflicting_agents(near) == set()
    # it left the line (holding points lie a reach or more off it) and reached its goal only after far passed
    assert np.abs(near.positions_m[:, 1]).max() > 0.5 * problem.reach_xy_m
    passes_goal = int(np.argmax(far.track.positions_m[:, 0] >= problem.goals_m[NEAR][0]))
    assert near.arrival_step > passes_goal
    timed = {problem.names[FAR]: far.track.timed_path(), problem.names[NEAR]: near.timed_path()}
    assert verify_plan(assemble_plan(sc, timed, method="swarm", notes=[]), sc) == []
    again = plan_via_holding(Occupancy(problem, [far.track], HORIZON), NEAR, through=False)
    assert again is not None
    np.testing.assert_array_equal(near.positions_m, again.positions_m)


def test_holding_is_off_by_default():
    """Off by default: at 128 it did not make a pass complete and cost CPU (docs/planner.md, stop 59 21B)."""
    assert PriorityOptions(max_repairs=1).holding is False
