"""A pass of prioritised planning gives up once more vehicles fly in collision than its cap
(``PriorityOptions.max_in_collision``, :func:`proxplan.planner.swarm.priority.in_collision_cap`)."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.planfile import scenario_from_dict
from proxplan.planner.formations import grid_reshuffle
from proxplan.planner.swarm import swarm_problem
from proxplan.planner.swarm.lns import NEIGHBOURHOOD
from proxplan.planner.swarm.prioritised_stage import longest_first
from proxplan.planner.swarm.priority import LNS_PLANNINGS_PER_VEHICLE, in_collision_cap, prioritized_tracks
from proxplan.planner.swarm.priority_options import PrioritizedFailed, PriorityOptions


def test_the_cap_is_the_collision_repairs_full_neighbourhoods():
    for n in (16, 64, 128, 256, 1000):
        assert in_collision_cap(n) == (LNS_PLANNINGS_PER_VEHICLE * n) // NEIGHBOURHOOD
    assert in_collision_cap(128) > in_collision_cap(64)


def test_a_pass_over_its_cap_gives_up_early_and_says_so_and_under_it_plans_as_without():
    """grid-20 (seed 0), longest line first, no repairs: without a cap the pass leaves vehicles in
    collision and the collision repair removes them (tests/planner/test_swarm_lns.py). With a cap of
    none in collision it gives up at the first one, before the repair, charged at least what it made
    and no more than its budget; with a cap of every vehicle the tracks are those without a cap."""
    problem = swarm_problem(scenario_from_dict(grid_reshuffle(20, seed=0), label="test scenario"))
    order = longest_first(problem)
    kw = dict(max_repairs=0, through=False, hold_s=1.0)
    free = prioritized_tracks(problem, order, PriorityOptions(**kw), horizon_steps=1200)
    assert free.collision_repairs >= 1
    budget = 10 * problem.n_agents
    with pytest.raises(PrioritizedFailed) as err:
        prioritized_tracks(
            problem, order, PriorityOptions(**kw, max_in_collision=0, max_plannings=budget), horizon_steps=1200
        )
    assert "1 vehicles in collision, more than the 0" in err.value.history[-1]
    assert err.value.planned < free.planned
    assert err.value.planned <= err.value.charged <= budget
    capped = prioritized_tracks(
        problem, order, PriorityOptions(**kw, max_in_collision=problem.n_agents), horizon_steps=1200
    )
    assert capped.planned == free.planned
    for a, tr in free.tracks.items():
        np.testing.assert_array_equal(tr.positions_m, capped.tracks[a].positions_m)
