"""The goal assignment's costs round the obstacles (proxplan.planner.swarm.obstacle_costs, issue 37 item 5,
round 24S): a certified bound per start-goal pair, so the assignment's bound B stays a lower bound and
weighs the way round an obstacle where a straight line would pass through it."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.planfile import scenario_from_dict
from proxplan.planner.bounds import certified_bound, straight_time_s
from proxplan.planner.formations import layout_doc
from proxplan.planner.swarm.assign import assign_by_type
from proxplan.planner.swarm.goals import apply_assignment
from proxplan.planner.swarm.obstacle_costs import pair_bounds_s
from proxplan.planner.swarm.problem import swarm_problem


@pytest.fixture(scope="module")
def corridor64():
    return scenario_from_dict(layout_doc("corridor", 64, assign="by_type"), label="test")


def test_pair_bounds_are_below_every_free_straight_line_and_zero_on_one_side(corridor64):
    """A pair on one side of every wall has no bound round it (0); a pair across a wall whose straight line
    is free (through the gap) gets a bound no larger than that line's time (a lower bound: the line is one
    way round); some pair across is blocked and bounded above its straight line's time."""
    scenario = corridor64
    names = list(scenario.vehicles)
    floor = pair_bounds_s(scenario, names)
    problem = swarm_problem(scenario)  # its static free space: the planner's inflated obstacles
    starts = np.array([scenario.vehicles[n].start_m for n in names])
    goals = np.array([scenario.vehicles[n].goal_m for n in names])
    same_side = np.sign(starts[:, None, 0]) == np.sign(goals[None, :, 0])
    assert np.all(floor[same_side] == 0.0)
    above = 0
    for i in range(len(names)):
        lim = scenario.vehicles[names[i]].kinematic_limits
        for g in np.flatnonzero(~same_side[i]):
            straight = straight_time_s(float(np.linalg.norm(goals[g] - starts[i])), lim)
            assert floor[i, g] > 0.0
            if problem.segment_free(starts[i], goals[g]):
                assert floor[i, g] <= straight + 1e-9
            above += int(floor[i, g] > straight + 1e-6)
    assert above > 0


def test_the_assignments_bound_weighs_the_way_round_and_stays_certified(corridor64):
    """corridor-64 by type: the same assignment as with straight-line costs (on the named layouts the
    costs round the wall changed none), but its bound B is the way round the wall: above the straight
    bound (1.75 -> 2.05 s when written) and equal to the certified bound of the assigned scenario
    (``bounds.certified_bound``, proven), so no plan can beat it."""
    scenario = corridor64
    assigned, record = apply_assignment(scenario)
    assert record is not None
    names = list(scenario.vehicles)
    tasks = [scenario.vehicles[n] for n in names]
    args = (
        np.array([t.start_m for t in tasks]),
        np.array([t.goal_m for t in tasks]),
        [t.type_name for t in tasks],
        [t.kinematic_limits for t in tasks],
    )
    straight = assign_by_type(*args)
    assert [names[int(k)] for k in straight.goal_of] == [record["goal_of"][n] for n in names]
    assert record["lower_bound_s"] > straight.lower_bound_s + 0.1
    assert record["lower_bound_s"] == pytest.approx(certified_bound(assigned).bound_s, abs=1e-6)
