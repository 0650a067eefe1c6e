"""Prioritised planning in the swarm layer (proxplan.planner.swarm.priority, components, chain):
groups planned apart the same in parallel, give-ups that survive pickling and count budgets, chains
flown through their corners, and the prediction of vehicles not planned yet."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.planfile import scenario_from_dict
from proxplan.planner.formations import grid_reshuffle
from proxplan.planner.swarm import swarm_problem


def test_groups_that_never_interact_are_planned_apart_the_same_in_parallel_as_in_turn():
    """Two formations far apart are two groups of the interaction graph; planned on a Dask local
    cluster (two workers) they get exactly the tracks they get one after the other."""
    from proxplan.planner.swarm.components import interaction_groups, plan_groups
    from proxplan.planner.swarm.prioritised_stage import longest_first
    from proxplan.planner.swarm.priority_options import PriorityOptions

    west, east = grid_reshuffle(6, seed=1), grid_reshuffle(6, seed=2)
    vehicles = {}
    for shift, doc in ((-6.0, west), (6.0, east)):
        for name, v in doc["vehicles"].items():
            start, goal = list(v["start"]), list(v["goal"])
            start[0] += shift
            goal[0] += shift
            vehicles[f"{'w' if shift < 0 else 'e'}{name}"] = {**v, "start": start, "goal": goal}
    doc = {**west, "name": "two-groups", "vehicles": vehicles}
    doc["workspace"] = {"min": [-9.0, -3.0, 0.0], "max": [9.0, 3.0, 3.0]}
    problem = swarm_problem(scenario_from_dict(doc, label="test scenario"))
    groups = interaction_groups(problem)
    assert [len(g) for g in groups] == [6, 6]
    options = PriorityOptions(max_repairs=12)
    kw = dict(horizon_steps=1200, fanout_min_vehicles=1)
    serial = plan_groups(problem, groups, longest_first, options, workers=1, **kw)
    parallel = plan_groups(problem, groups, longest_first, options, workers=2, **kw)
    assert sorted(serial.tracks) == list(range(12))
    for a, tr in serial.tracks.items():
        np.testing.assert_array_equal(tr.positions_m, parallel.tracks[a].positions_m)


def test_a_give_up_pickled_back_from_a_dask_worker_keeps_its_fields():
    """A group that gives up on a Dask worker comes back as a PrioritizedFailed with its vehicle,
    repairs, history and count of plannings (the default exception pickling passes the message only,
    and unpickling failed)."""
    import pickle

    from proxplan.planner.swarm.priority_options import PrioritizedFailed

    failed = pickle.loads(pickle.dumps(PrioritizedFailed(3, 1, ["v003: nobody to take out"], planned=5, charged=9)))
    assert isinstance(failed, PrioritizedFailed)
    assert (failed.agent, failed.repairs, failed.history, failed.planned, failed.charged) == (
        3,
        1,
        ["v003: nobody to take out"],
        5,
        9,
    )


def test_a_pass_given_up_early_is_one_that_would_spend_its_budget():
    """grid-20 (seed 0), dependencies first, reserved starts: a pass needs P plannings (measured in
    the test). With a budget of P, giving up early changes nothing (the same tracks); with P - 1 the
    pass gives up both ways, early after no more plannings, charged the whole budget, and the pass
    without it spends the budget (here both at the last vehicle); with one planning per vehicle it gives up at its first vehicle
    planned twice, long before the budget is spent."""
    from proxplan.planner.sampling.ordering import lower_bound_makespan_s
    from proxplan.planner.swarm.prioritised_stage import ORDERS, horizon_steps
    from proxplan.planner.swarm.priority import prioritized_tracks
    from proxplan.planner.swarm.priority_options import PrioritizedFailed, PriorityOptions

    sc = scenario_from_dict(grid_reshuffle(20, seed=0), label="test scenario")
    problem = swarm_problem(sc)
    horizon = horizon_steps(lower_bound_makespan_s(sc))
    order = ORDERS["dependencies first"](problem)
    kw = dict(max_repairs=4, hold_s=1.0, reserve_starts=True, through=False)
    free = prioritized_tracks(problem, order, PriorityOptions(**kw), horizon_steps=horizon)
    budget = free.planned
    assert budget > problem.n_agents, "the pass must plan some vehicle more than once"
    for early in (False, True):
        got = prioritized_tracks(
            problem, order, PriorityOptions(**kw, max_plannings=budget, give_up_early=early), horizon_steps=horizon
        )
        assert got.planned == budget
        for a, tr in free.tracks.items():
            np.testing.assert_array_equal(tr.positions_m, got.tracks[a].positions_m)
    for short in (budget - 1, problem.n_agents):
        fails = {}
        for early in (False, True):
            with pytest.raises(PrioritizedFailed) as err:
                prioritized_tracks(
                    problem,
                    order,
                    PriorityOptions(**kw, max_plannings=short, give_up_early=early),
                    horizon_steps=horizon,
                )
            fails[early] = err.value
        assert fails[False].planned >= short and fails[False].charged == fails[False].planned
        assert fails[True].planned <= fails[False].planned and fails[True].charged == short
    assert "given up early" in fails[True].history[-1]
    assert fails[True].planned < problem.n_agents, "with one planning per vehicle it gives up at its first re-plan"


def test_a_chain_is_flown_through_its_corner_when_nothing_is_in_the_way():
    """Safe-interval timing along a chain with a gentle corner: flying through the waypoint arrives
    earlier than stopping there, and where another vehicle sits on the corner the timing waits for it
    (it never flies through a conflict)."""
    from proxplan.planner.swarm.chain import time_chain
    from proxplan.planner.swarm.occupancy import Occupancy
    from proxplan.planner.swarm.tracks import GridTrack
    from proxplan.planner.timing.profile import LineMove, rest_to_rest

    doc = grid_reshuffle(2, types=["crazyflie-2.1"])
    doc["workspace"] = {"min": [-3.0, -3.0, 0.0], "max": [3.0, 3.0, 3.0]}
    doc["obstacles"] = [{"min": [-0.2, -2.0, 0.0], "max": [0.2, -0.7, 3.0]}]  # no straight line from start to goal
    doc["vehicles"]["v000"].update(start=[-2.0, -1.0, 1.5], goal=[2.0, -0.6, 1.5])
    doc["vehicles"]["v001"].update(start=[-2.5, 2.5, 1.5], goal=[-2.5, 2.0, 1.5])
    problem = swarm_problem(scenario_from_dict(doc, label="test scenario"))
    W = np.array([[-2.0, -1.0, 1.5], [0.0, 0.0, 1.5], [2.0, -0.6, 1.5]])  # a 43-degree corner above the box
    empty = Occupancy(problem, [], 800)
    through = time_chain(empty, 0, W, through=True)
    stops = time_chain(empty, 0, W, through=False)
    assert through is not None and stops is not None
    assert through.arrival_step < stops.arrival_step
    # the other vehicle crosses the corner early on: the chain must not be there at the same time
    a, b = np.array([0.0, 2.5, 1.5]), np.array([0.0, -0.5, 1.5])  # it comes down over the corner, waits, goes back
    cross = LineMove(a, b, rest_to_rest(3.0, problem.limits[1], 0.025))
    other = GridTrack(
        1,
        int(problem.type_index[1]),
        a,
        [(0, cross), (120, LineMove(b, a, rest_to_rest(3.0, problem.limits[1], 0.025)))],
    )
    busy = Occupancy(problem, [other], 800)
    timed = time_chain(busy, 0, W, through=True)
    assert timed is not None
    assert not busy.conflicting_agents(timed.track)
    assert timed.arrival_step > through.arrival_step  # it let the other one pass
    assert Occupancy(problem, [other], 800).conflicting_agents(through.track) == {1}  # the free timing would hit it


def test_a_vehicle_not_planned_yet_is_predicted_to_leave_on_its_straight_line_and_then_vanish():
    from proxplan.planner.swarm.priority import predicted_track

    problem = swarm_problem(scenario_from_dict(grid_reshuffle(9, seed=4), label="test scenario"))
    a = int(np.argmax(np.linalg.norm(problem.goals_m - problem.starts_m, axis=1)))
    held = predicted_track(problem, a, hold_s=1.0)
    assert held.vanishes
    hold = int(round(1.0 / 0.025))
    np.testing.assert_allclose(held.positions_m[: hold + 1], np.repeat(problem.starts_m[a][None], hold + 1, axis=0))
    last = held.positions_m[-1]
    reach = max(k.reach_xy_m for (ta, _), k in problem.keepouts.items() if ta == int(problem.type_index[a]))
    assert np.linalg.norm(last[:2] - problem.starts_m[a][:2]) > reach  # it has left its start's reach
    assert np.linalg.norm(last - problem.goals_m[a]) > 1e-6  # and is not followed to its goal
