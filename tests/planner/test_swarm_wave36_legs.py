"""A wavefront route's legs stay statically free (proxplan.planner.swarm.wave_path; issue 37, round 36S).

Pillar-128 by type: three vehicles whose assigned straight lines cross the pillar (v008, v024, v055) got a
route round it whose simplified legs cut into the inflated pillar, so no timing existed even alone
(``reserve.ideal_track`` None) and every prioritised pass gave up on the first of them ("nobody to take
out"). Here those three vehicles alone, with their assigned starts and goals: every leg of the route is
statically free, each has a track alone, and the route still deviates from its cells by at most a cell
where it was simplified."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.planfile import scenario_from_dict
from proxplan.planner.formations import LAYOUTS
from proxplan.planner.swarm import swarm_problem
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.reserve import ideal_track
from proxplan.planner.swarm.wave import wave_route
from proxplan.planner.swarm.wave_path import cell_route_waypoints

HORIZON = 959  # pillar-128 by type's prioritised horizon (prioritised_stage.horizon_steps of its bound)

# (type, start, assigned goal) of the vehicles of pillar-128 by type whose routes round the pillar had a leg
# through it (goals.apply_assignment on LAYOUTS["pillar"](128), main 3b53525)
CROSSING = {
    "v008": ("small-quad", [-0.8, 0.3, 1.0], [5.0, -0.3, 1.0]),
    "v024": ("crazyflie-2.1", [-1.4, 0.3, 1.0], [4.7, 0.0, 1.5]),
    "v055": ("crazyflie-parrot", [-2.9, 0.0, 1.5], [3.2, 0.3, 1.0]),
}


def _problem():
    doc = LAYOUTS["pillar"](128)  # its workspace, pillar and limits; only these three vehicles
    doc["vehicles"] = {name: {"type": t, "start": s, "goal": g} for name, (t, s, g) in CROSSING.items()}
    return swarm_problem(scenario_from_dict(doc))


@pytest.mark.parametrize("name", sorted(CROSSING))
def test_route_round_the_pillar_has_free_legs_and_a_track(name):
    problem = _problem()
    a = problem.names.index(name)
    s, g = problem.starts_m[a], problem.goals_m[a]
    assert not problem.segment_free(s, g)  # the straight line crosses the pillar: a route is needed
    route = wave_route(Occupancy(problem, [], HORIZON), a, s, g)
    assert route is not None and len(route) > 2
    assert all(problem.segment_free(route[k], route[k + 1]) for k in range(len(route) - 1))
    track = ideal_track(problem, a, HORIZON)
    assert track is not None
    assert track.arrival_step < HORIZON


def test_corner_put_back_only_where_a_leg_is_not_free():
    """A staircase round a blocked square: without a static test the simplification cuts the corner
    (one leg), with a test that forbids the corner's inside the corner comes back; with a test that
    forbids nothing the waypoints are those of the simplification alone."""
    # an L-shaped cell route: 10 cells east, then 10 north (corner at cell (10, 0))
    cells = [(i, 0) for i in range(11)] + [(10, j) for j in range(1, 11)]
    # a staircase below the diagonal, one cell off it at most: simplified to one leg
    stairs = [(0, 0)]
    for k in range(1, 11):
        stairs += [(k, k - 1), (k, k)]
    lo, h = np.zeros(2), 0.1
    start, goal = np.array([0.0, 0.0, 1.0]), np.array([1.0, 1.0, 1.0])
    plain = cell_route_waypoints(stairs, lo, h, start, goal, heights=False)
    assert len(plain) == 2  # within a cell of the diagonal: one leg

    def blocked_square(p0, p1):  # a box just above the diagonal's middle: the chord crosses it, the stairs not
        t = np.linspace(0.0, 1.0, 201)[:, None]
        q = p0[:2] * (1 - t) + p1[:2] * t
        inside = (q[:, 0] > 0.5) & (q[:, 0] < 0.58) & (q[:, 1] > 0.56) & (q[:, 1] < 0.62)
        return not bool(inside.any())

    kept = cell_route_waypoints(stairs, lo, h, start, goal, heights=False, segment_free=blocked_square)
    assert len(kept) > 2
    assert all(blocked_square(kept[k], kept[k + 1]) for k in range(len(kept) - 1))
    free = cell_route_waypoints(stairs, lo, h, start, goal, heights=False, segment_free=lambda p0, p1: True)
    np.testing.assert_array_equal(free, plain)
    corner = cell_route_waypoints(cells, lo, h, start, goal, heights=False, segment_free=lambda p0, p1: True)
    np.testing.assert_allclose(corner[:, :2], [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]])


def test_put_back_ends_where_no_leg_is_ever_free():
    """A route that waits at its start, with a static test that frees no leg (the worst case for the loop):
    the put-back ends once every corner is back, with the exact start and goal."""
    cells = [(3, 3), (3, 3), (3, 3), (4, 4), (4, 4)]
    lo, h = np.zeros(2), 0.1
    start, goal = np.array([0.3, 0.3, 1.0]), np.array([0.4, 0.4, 1.2])
    plain = cell_route_waypoints(cells, lo, h, start, goal, heights=False)
    never = cell_route_waypoints(cells, lo, h, start, goal, heights=False, segment_free=lambda p0, p1: False)
    assert len(never) >= len(plain)
    assert np.array_equal(never[0], start) and np.array_equal(never[-1], goal)
