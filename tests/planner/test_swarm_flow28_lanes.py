"""The lane stage's flow order and restarts (round 28A, docs/planner.md "Stop 66, round 28A"): a vehicle whose
start is within keep-out of another's goal is ordered before it (``ORDER_BY_ENDS``); the flow timing never
times an order twice (the timing is a function of the order), so two vehicles that cannot pass each other
end it after one restart instead of ``FLOW_RESTARTS``, and the same problem ends the same way twice."""

from __future__ import annotations

import numpy as np

from proxplan.planfile import scenario_from_dict
from proxplan.planner.swarm import lanes, swarm_problem
from proxplan.planner.swarm.lanes import (
    FLOW_RESTARTS,
    KEEP_RIGHT,
    flow_order,
    flow_timing,
    lane_routes,
)
from proxplan.planner.swarm.occupancy import Occupancy

HORIZON = 2000  # grid steps (50 s): far beyond every flight here (a few seconds each)


def _tube(vehicles: dict, half_width_m: float) -> object:
    """Vehicles in a straight tube along x, ``half_width_m`` wide either side of y = 0 and 1 m to 2 m high."""
    doc = {
        "name": "tube",
        "workspace": {"min": [-3.0, -half_width_m, 1.0], "max": [3.0, half_width_m, 2.0]},
        "obstacles": [],
        "limits": {"authority_fraction": 0.1, "min_separation_m": 0.25},
        "vehicles": {k: {"type": "crazyflie-2.1", "start": s, "goal": g} for k, (s, g) in vehicles.items()},
    }
    return swarm_problem(scenario_from_dict(doc, label="tube"))


def test_a_vehicle_leaves_before_the_one_arriving_at_its_start(monkeypatch):
    # in a narrow tube v000 flies to v001's start, v001 on ahead: the longer flight first would put v000 first
    problem = _tube({"v000": ([-2.5, 0.0, 1.5], [0.0, 0.0, 1.5]), "v001": ([0.0, 0.0, 1.5], [0.8, 0.0, 1.5])}, 0.3)
    _, hits = lane_routes(problem, HORIZON, KEEP_RIGHT)
    assert flow_order(problem, hits, HORIZON) == ([1, 0], 0)
    monkeypatch.setattr(lanes, "ORDER_BY_ENDS", False)
    assert flow_order(problem, hits, HORIZON) == ([0, 1], 0)
    monkeypatch.undo()
    tracks, how = flow_timing(problem, *lane_routes(problem, HORIZON, KEEP_RIGHT), HORIZON)
    assert len(tracks) == 2, how
    others = Occupancy(problem, [tracks[1]], HORIZON)
    assert not others.conflicting_agents(tracks[0])
    np.testing.assert_allclose(tracks[0].positions_m[-1], problem.goals_m[0])


def test_two_vehicles_that_cannot_pass_end_the_restarts_at_once():
    # v000 must overtake v001 in a tube too narrow to pass side by side, above or below: no plan exists, and
    # either order fails at the other vehicle, so the third order would repeat the first
    tube = {"v000": ([-2.0, 0.0, 1.5], [2.0, 0.0, 1.5]), "v001": ([-1.0, 0.0, 1.5], [1.0, 0.0, 1.5])}
    problem = _tube(tube, 0.3)
    tracks, how = flow_timing(problem, *lane_routes(problem, HORIZON, KEEP_RIGHT), HORIZON)
    assert len(tracks) < 2
    assert "the order repeats" in how, how
    restarts = int(how.split(" restarts")[0].rsplit(" ", 1)[-1])
    assert restarts < FLOW_RESTARTS // 2, how
    again, how_again = flow_timing(problem, *lane_routes(problem, HORIZON, KEEP_RIGHT), HORIZON)
    assert how_again == how and sorted(again) == sorted(tracks)
