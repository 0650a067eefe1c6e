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
from proxplan.planner.swarm.priority import prioritized_tracks
from proxplan.planner.swarm.priority_options import PrioritizedFailed, PriorityOptions
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


def test_the_collision_repair_gives_up_early_when_its_count_left_cannot_remove_the_pairs():
    """Disjoint colliding pairs need one planning each (plannings_needed); 60 of them with 10
    plannings left (a neighbourhood may then make at most HOOD_PLANNINGS more) cannot all go: the
    repair gives up before planning anyone, with the reason; with a budget that could suffice it
    plans."""
    from types import SimpleNamespace

    from proxplan.planner.swarm.lns import HOOD_PLANNINGS, plannings_needed, remove_collisions

    assert plannings_needed({(0, 1), (1, 2), (2, 3)}) == 2
    assert plannings_needed({(0, 1), (0, 2), (0, 3)}) == 1
    n = 120
    partner = {a: a ^ 1 for a in range(n)}  # pairs (0, 1), (2, 3), ...

    class Occ:
        problem = SimpleNamespace(pinned=np.zeros(n, dtype=bool))
        tracks = {a: SimpleNamespace(agent=a, vanishes=False) for a in range(n)}

        def conflicting_agents(self, track):
            return {partner[track.agent]}

        def put(self, track):
            pass

        def remove(self, agent):
            return None

    calls = []

    def plan_one(occ, b):
        calls.append(b)
        return None

    kw = dict(
        plan_one=plan_one,
        plan_ignoring=lambda occ, b, hood: Occ.tracks[b],
        predicted=lambda b: Occ.tracks[b],
        extra_neighbours=lambda b: set(),
        seed=0,
    )
    early: list[str] = []
    budget = 10
    assert plannings_needed({(a, a + 1) for a in range(0, n, 2)}) > budget - 1 + HOOD_PLANNINGS
    plannings, tried, pairs = remove_collisions(
        Occ(), dict(Occ.tracks), list(range(n)), budget=budget, early=early, **kw
    )
    assert (plannings, tried, pairs) == (0, 0, n // 2) and not calls
    assert early and "given up early" in early[0]
    early.clear()
    plannings, tried, pairs = remove_collisions(
        Occ(), dict(Occ.tracks), list(range(n)), budget=4 * n, early=early, **kw
    )
    assert calls and plannings >= 1 and pairs == n // 2  # the stub never removes a pair
