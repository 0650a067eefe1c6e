"""Routes raised over the others (proxplan.planner.swarm.raised, round 29A): a vehicle that must overtake
another on one line, with no room beside the line at its height, passes over it; the raised chains rise
from the start, fly at the raised height beside the line and come down onto the goal; never a later
arrival than the flat planning; the same track every time; the plan passes the verifier."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from proxplan.planfile import scenario_from_dict
from proxplan.planner.formations import LAYOUTS
from proxplan.planner.swarm import swarm_problem
from proxplan.planner.swarm.chain import time_chain
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.priority import prioritized_tracks
from proxplan.planner.swarm.priority_options import PrioritizedFailed, PriorityOptions
from proxplan.planner.swarm.raised import RAISE_DZ_M, SIDE_MARGIN_M, raised_chains, raised_or
from proxplan.planner.swarm.single import plan_one
from proxplan.planner.timing import assemble_plan
from proxplan.verify import verify_plan

HORIZON = 1200
FAR, NEAR = 0, 1


def _in_line(half_width_m: float, top_m: float = 3.0):
    """``far`` (6 m) flies through ``near``'s start and goal (2 m, in the middle of it), both Crazyflies at
    1.5 m; the box ``half_width_m`` either side of the line (0.45 m: no room to pass beside at one height,
    the keep-out's horizontal reach at one height is 0.32 m)."""
    doc = {
        "name": "in-line",
        "workspace": {"min": [-4.0, -half_width_m, 0.0], "max": [4.0, half_width_m, top_m]},
        "limits": {"authority_fraction": 0.1, "min_separation_m": 0.25},
        "vehicles": {
            "far": {"type": "crazyflie-2.1", "start": [-3.0, 0.0, 1.5], "goal": [3.0, 0.0, 1.5]},
            "near": {"type": "crazyflie-2.1", "start": [-1.0, 0.0, 1.5], "goal": [1.0, 0.0, 1.5]},
        },
    }
    sc = scenario_from_dict(doc, label="test scenario")
    return sc, swarm_problem(sc)


def _near_first(problem):
    """near flown first along its line from t = 0, then parked at its goal on far's line for good."""
    empty = Occupancy(problem, [], HORIZON)
    near = time_chain(empty, NEAR, np.array([problem.starts_m[NEAR], problem.goals_m[NEAR]]), through=False)
    assert near is not None
    return near.track


def test_raised_chains_rise_beside_the_line_and_come_down_onto_the_goal():
    _, problem = _in_line(0.45)
    occ = Occupancy(problem, [], HORIZON)
    s, g = problem.starts_m[FAR], problem.goals_m[FAR]
    chains = raised_chains(occ, FAR, np.array([s, g]))
    assert len(chains) == 3 * len(RAISE_DZ_M)  # above the line, right and left of it, at each height
    ko = problem.keepouts[(0, 0)]
    for k, chain in enumerate(chains):
        dz = RAISE_DZ_M[k // 3]
        np.testing.assert_array_equal(chain[0], s)
        np.testing.assert_array_equal(chain[-1], g)
        assert len(chain) == 4 and np.allclose(chain[1:3, 2], s[2] + dz)
        side = abs(chain[1, 1])
        assert side == 0.0 or np.isclose(side, ko.horizontal_radius_m(dz, dz) + SIDE_MARGIN_M)
        assert np.isclose(chain[1, 1], chain[2, 1])  # one side all along
    # a box too low for the raised heights gives none
    _, low = _in_line(0.45, top_m=1.9)
    assert low.hi_m[2] < s[2] + min(RAISE_DZ_M)
    assert raised_chains(Occupancy(low, [], HORIZON), FAR, np.array([s, g])) == []


def test_far_passes_over_near_where_no_flat_route_can_and_the_plan_verifies():
    sc, problem = _in_line(0.45)
    near = _near_first(problem)
    occ = Occupancy(problem, [near], HORIZON)
    assert plan_one(occ, FAR, False) is None  # no room beside the line at its height
    far = raised_or(occ, FAR, False, None)
    assert far is not None
    assert occ.conflicting_agents(far) == set()
    assert far.positions_m[:, 2].max() > problem.starts_m[FAR][2] + 0.4  # it rose over near
    timed = {problem.names[FAR]: far.timed_path(), problem.names[NEAR]: near.timed_path()}
    assert verify_plan(assemble_plan(sc, timed, method="swarm", notes=[]), sc) == []
    again = raised_or(Occupancy(problem, [near], HORIZON), FAR, False, None)
    assert again is not None
    np.testing.assert_array_equal(far.positions_m, again.positions_m)


def test_never_later_than_the_flat_planning():
    """With room beside the line (1.2 m) the flat planning finds a track; the raised ones are kept only
    where strictly earlier, so the result arrives no later; a track at the unobstructed time is kept as is."""
    _, problem = _in_line(1.2)
    occ = Occupancy(problem, [_near_first(problem)], HORIZON)
    flat = plan_one(occ, FAR, False)
    assert flat is not None
    got = raised_or(occ, FAR, False, flat)
    assert got is not None and got.arrival_step <= flat.arrival_step
    alone = plan_one(Occupancy(problem, [], HORIZON), FAR, False)
    assert raised_or(Occupancy(problem, [], HORIZON), FAR, False, alone) is alone


def test_a_pass_with_raised_routes_plans_the_pair_the_same_every_time():
    """The pass in the order near, far: without raised routes far cannot be planned past near parked on its
    line; with them the pass gives conflict-free tracks, the same twice."""
    _, problem = _in_line(0.45)
    flat = PriorityOptions(max_repairs=0, collisions=False)
    with pytest.raises(PrioritizedFailed):
        prioritized_tracks(problem, [NEAR, FAR], flat, horizon_steps=HORIZON)
    options = replace(flat, raised=True)
    one = prioritized_tracks(problem, [NEAR, FAR], options, horizon_steps=HORIZON)
    two = prioritized_tracks(problem, [NEAR, FAR], options, horizon_steps=HORIZON)
    occ = Occupancy(problem, [one.tracks[NEAR]], HORIZON)
    assert occ.conflicting_agents(one.tracks[FAR]) == set()
    for a in (NEAR, FAR):
        np.testing.assert_array_equal(one.tracks[a].positions_m, two.tracks[a].positions_m)


def test_raised_routes_only_on_a_top_or_bottom_level_of_the_stacked_plan():
    """corridor-16: the whole swarm (two heights) is not a level; each of its stacked plan's levels is (its
    starts and goals at the level's height, the floor or ceiling of its band); grid-16, flat with room
    above and below, is not."""
    from dataclasses import replace as _replace

    from proxplan.planner.swarm.hand_on import level_stacking
    from proxplan.planner.swarm.levels import levelled_endpoints, stack_levels
    from proxplan.planner.swarm.raised import a_level
    from proxplan.planner.swarm.stacked import level_subproblem

    sc = scenario_from_dict(LAYOUTS["corridor"](16), label="corridor-16")
    problem = swarm_problem(sc)
    assert not a_level(problem)
    levels = stack_levels(problem, level_stacking(sc, problem)())
    assert levels is not None and len(levels.groups) >= 2
    lev_s, lev_g = levelled_endpoints(problem, levels)
    on_levels = _replace(problem, starts_m=lev_s, goals_m=lev_g)
    for k, group in enumerate(levels.groups):
        agents = [a for a in range(problem.n_agents) if int(problem.type_index[a]) in group]
        assert a_level(level_subproblem(on_levels, agents, levels.band_m(k)))
    assert not a_level(swarm_problem(scenario_from_dict(LAYOUTS["grid"](16), label="grid-16")))
