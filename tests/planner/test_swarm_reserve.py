"""Reserved starts (proxplan.planner.swarm.priority, ``reserve_starts``): a vehicle not planned yet
holds its start until it is planned; nobody plans through it unless it is released for them, and a
released vehicle is planned next."""

from __future__ import annotations

import math

import numpy as np
import pytest

from proxplan.planfile import scenario_from_dict
from proxplan.planner.formations import formation_change
from proxplan.planner.swarm import swarm_problem
from proxplan.planner.swarm.lns import colliding_pairs
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.priority import (
    PrioritizedFailed,
    PriorityOptions,
    dependency_order,
    prioritized_tracks,
)
from proxplan.planner.swarm.reserve import reserved_track
from proxplan.planner.timing import assemble_plan
from proxplan.verify import verify_plan

HORIZON = 1200


def test_a_reserved_start_forbids_every_departure_through_it():
    """The reservation is a track parked at the start for good: a move through it is forbidden at
    every departure, a move that keeps its distance at none."""
    sc = scenario_from_dict(formation_change(16), label="test scenario")
    problem = swarm_problem(sc)
    occ = Occupancy(problem, [reserved_track(problem, 1)], HORIZON)
    s1 = problem.starts_m[1]
    through = np.linspace(s1 - [0.5, 0.0, 0.0], s1 + [0.5, 0.0, 0.0], 41)
    assert occ.forbidden_departures(0, through).all()
    away = through + [0.0, 0.0, 5.0 * problem.reach_xy_m]
    away[:, :2] += 5.0 * problem.reach_xy_m
    assert not occ.forbidden_departures(0, away).any()


def test_pillar_16_start_traps_with_predictions_and_plans_with_reserved_starts():
    """pillar-16 (two staggered layers flying past the pillar), dependency order, the swarm layer's
    per-vehicle repair budget: with every unplanned vehicle predicted to leave after 1 s the pass
    gives up (later vehicles cannot leave before the earlier ones come through their starts, and the
    collision repair does not remove every pair); with reserved starts every vehicle is planned
    (measured when written: 16 plannings, no repair, of a budget of 96), no pair collides, the plan
    passes the verifier, and the same options give the same tracks."""
    sc = scenario_from_dict(formation_change(16), label="test scenario")
    problem = swarm_problem(sc)
    order = dependency_order(problem)
    kw = dict(max_repairs=math.ceil(0.25 * 16), max_plannings=6 * 16, hold_s=1.0, through=False)
    with pytest.raises(PrioritizedFailed):
        prioritized_tracks(problem, order, PriorityOptions(**kw), horizon_steps=HORIZON)
    result = prioritized_tracks(problem, order, PriorityOptions(**kw, reserve_starts=True), horizon_steps=HORIZON)
    assert sorted(result.tracks) == list(range(problem.n_agents))
    assert result.collision_repairs == 0
    occ = Occupancy(problem, list(result.tracks.values()), HORIZON)
    assert colliding_pairs(occ, range(problem.n_agents)) == set()
    timed = {problem.names[a]: tr.timed_path() for a, tr in result.tracks.items()}
    assert verify_plan(assemble_plan(sc, timed, method="swarm", notes=[]), sc) == []
    again = prioritized_tracks(problem, order, PriorityOptions(**kw, reserve_starts=True), horizon_steps=HORIZON)
    for a, tr in result.tracks.items():
        np.testing.assert_array_equal(tr.positions_m, again.tracks[a].positions_m)
