"""Prioritised planning that does not give up a pass (proxplan.planner.swarm.lns): a vehicle that
cannot be planned flies in collision and the collisions are repaired a neighbourhood at a time."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.planfile import scenario_from_dict
from proxplan.planner.formations import grid_reshuffle
from proxplan.planner.swarm import swarm_problem
from proxplan.planner.swarm.lns import colliding_pairs
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.prioritised_stage import longest_first
from proxplan.planner.swarm.priority import (
    PrioritizedFailed,
    PriorityOptions,
    prioritized_tracks,
)
from proxplan.planner.timing import assemble_plan
from proxplan.verify import verify_plan


def test_a_pass_that_would_give_up_repairs_its_collisions_and_the_plan_verifies():
    """grid-20 (seed 0), longest line first, no repairs: the pass gives up at its first vehicle that
    cannot be planned; with the collision repair it goes on, and one neighbourhood (measured when
    written: 26 plannings in all, the repair's budget 20 of its own) leaves no colliding pair; the
    plan passes the verifier, and the same seed gives the same tracks."""
    sc = scenario_from_dict(grid_reshuffle(20, seed=0), label="test scenario")
    problem = swarm_problem(sc)
    order = longest_first(problem)
    kw = dict(max_repairs=0, through=False, hold_s=1.0)
    with pytest.raises(PrioritizedFailed):
        prioritized_tracks(problem, order, PriorityOptions(**kw, collisions=False), horizon_steps=1200)
    result = prioritized_tracks(problem, order, PriorityOptions(**kw), horizon_steps=1200)
    assert result.collision_repairs >= 1
    assert sorted(result.tracks) == list(range(problem.n_agents))
    occ = Occupancy(problem, list(result.tracks.values()), 1200)
    assert colliding_pairs(occ, range(problem.n_agents)) == set()
    timed = {problem.names[a]: tr.timed_path() for a, tr in result.tracks.items()}
    assert verify_plan(assemble_plan(sc, timed, method="swarm", notes=[]), sc) == []
    again = prioritized_tracks(problem, order, PriorityOptions(**kw), horizon_steps=1200)
    for a, tr in result.tracks.items():  # the same seed, the same plan
        np.testing.assert_array_equal(tr.positions_m, again.tracks[a].positions_m)
