"""A frozen pair the unfreeze step cannot move (issue 37, stop 79): the swarm layer gives up before its search.

Two pairs of large quads end in round 37Z's goal geometry (each pair clear of its keep-out at rest, inside it
while either moves: frozen, ``swarm.frozen``), the second pair ``PAIR_GAP_M`` beside the first, so the two movers
the unfreeze step would choose are within reach of each other and it moves neither. No stage of the swarm layer can
plan the later arrival of a frozen pair; the layer used to learn it only when its search budget ran out."""

from __future__ import annotations

import pytest

from proxplan.planfile import scenario_from_dict
from proxplan.planner.errors import PlanNotFound
from proxplan.planner.swarm.frozen import frozen_unmoved, unfrozen_problem
from proxplan.planner.swarm.plan import swarm_timed
from proxplan.planner.swarm.problem import swarm_problem

from .test_goal_margin37z import DZ_M, _doc, _in_margin_m

PAIR_GAP_M = 0.6  # the second pair's goals beside the first's, along y, m (less the unfreeze moves: within reach)


def _two_frozen_pairs(gap_m: float) -> dict:
    x = _in_margin_m()
    doc = _doc(x)
    doc["vehicles"]["c"] = {"type": "large-quad", "start": [-1.5, -1.0, 1.0], "goal": [0.0, 1.0 + gap_m, 1.0]}
    doc["vehicles"]["e"] = {
        "type": "large-quad",
        "start": [1.5, -1.0, 1.0 + DZ_M],
        "goal": [x, 1.0 + gap_m, 1.0 + DZ_M],
    }
    return doc


def test_a_frozen_pair_left_by_the_unfreeze_step_is_named():
    problem = swarm_problem(scenario_from_dict(_two_frozen_pairs(PAIR_GAP_M)))
    unfrozen, _, why = unfrozen_problem(problem)
    assert "within reach" in why
    assert frozen_unmoved(unfrozen) == ["a", "b", "c", "e"]


def test_one_frozen_pair_is_unfrozen_and_nothing_is_left():
    problem = swarm_problem(scenario_from_dict(_doc(_in_margin_m())))
    assert frozen_unmoved(problem) == ["a", "b"]  # frozen before the unfreeze step
    unfrozen, unfreezes, _ = unfrozen_problem(problem)
    assert unfreezes and frozen_unmoved(unfrozen) == []


def test_the_swarm_layer_gives_up_before_its_search():
    scenario = scenario_from_dict(_two_frozen_pairs(PAIR_GAP_M))
    with pytest.raises(PlanNotFound, match="no stage of it moves a frozen pair") as err:
        swarm_timed(scenario)  # before stop 79: "no plan found within 4000 configuration proposals", after 1.3 s
    assert "configuration" not in err.value.message  # no search ran
    assert err.value.vehicles == ["a", "b", "c", "e"]
