"""The goal block filled from its far side (swarm.fill_order) and the stacked plan made beside the
prioritised plan (complete_stages.stacked_beside); round 24B."""

from __future__ import annotations

from types import SimpleNamespace

from proxplan.planfile.scenario_load import scenario_from_dict
from proxplan.planner.swarm import swarm_problem
from proxplan.planner.swarm.complete_stages import stacked_beside
from proxplan.planner.swarm.fill_order import fill_order, route_relations
from proxplan.planner.swarm.prioritised_stage import FAR_GOALS_FIRST, ORDERS, longest_first


def _problem(vehicles: dict):
    doc = {
        "name": "fill",
        "workspace": {"min": [-5.0, -2.5, 0.0], "max": [5.0, 2.5, 3.0]},
        "limits": {"authority_fraction": 0.1, "min_separation_m": 0.25},
        "vehicles": {
            name: {"type": "crazyflie-2.1", "start": list(s), "goal": list(g)} for name, (s, g) in vehicles.items()
        },
    }
    return swarm_problem(scenario_from_dict(doc, label="test scenario"))


def _column():
    """Three vehicles on one line at one height, the order reversed: the back one (x = -3) to the far
    goal (x = 3), the front one (x = -1) to the near goal (x = 1)."""
    return _problem(
        {
            "front": ((-1.0, 0.0, 1.5), (1.0, 0.0, 1.5)),
            "middle": ((-2.0, 0.0, 1.5), (2.0, 0.0, 1.5)),
            "back": ((-3.0, 0.0, 1.5), (3.0, 0.0, 1.5)),
        }
    )


def test_routes_pass_the_goals_in_front_and_starts_block_the_routes_behind():
    problem = _column()
    front, middle, back = (problem.names.index(n) for n in ("front", "middle", "back"))
    rel = route_relations(problem)
    assert rel.passes[back] == {front, middle}
    assert rel.passes[middle] == {front}
    assert rel.passes[front] == set()
    assert rel.blocks[front] == {middle, back}
    assert rel.blocks[middle] == {back}
    assert rel.blocks[back] == set()
    assert rel.length_m[back] > rel.length_m[middle] > rel.length_m[front]


def test_the_far_goal_is_filled_first_and_the_front_goal_last():
    problem = _column()
    order = [problem.names[a] for a in fill_order(problem)]
    assert order == ["back", "middle", "front"]


def test_a_short_route_through_a_goal_goes_before_the_longer_route_that_ends_there():
    """``cross`` (1.6 m) flies through the goal of ``long`` (3.5 m): the goal is filled after it has
    passed, although the longer line goes first in the longest-first order."""
    problem = _problem(
        {
            "long": ((-2.5, 0.0, 1.5), (1.0, 0.0, 1.5)),
            "cross": ((1.0, -0.8, 1.5), (1.0, 0.8, 1.5)),
        }
    )
    assert [problem.names[a] for a in longest_first(problem)] == ["long", "cross"]
    assert [problem.names[a] for a in fill_order(problem)] == ["cross", "long"]
    assert ORDERS[FAR_GOALS_FIRST] is fill_order


def test_a_cycle_still_gives_every_vehicle_once():
    """Two vehicles swapping along one line pass each other's goals (a cycle): each is placed once."""
    problem = _problem({"a": ((-1.0, 0.0, 1.5), (1.0, 0.0, 1.5)), "b": ((1.0, 0.0, 1.5), (-1.0, 0.0, 1.5))})
    rel = route_relations(problem)
    assert rel.passes[0] == {1} and rel.passes[1] == {0}
    assert sorted(fill_order(problem)) == [0, 1]


def _stage(name: str, arrivals: list[float]):
    from proxplan.planner.swarm.stage import Stage

    tracks = [SimpleNamespace(arrival_s=t) for t in arrivals]
    return Stage(tracks, name, name, lambda a: [])  # type: ignore[arg-type]


def test_the_stacked_plan_beside_is_kept_only_when_shorter():
    prioritised = _stage("prioritised", [3.0, 5.0])
    extra: dict = {"stacked": "levels"}
    kept = stacked_beside(prioritised, _stage("stacked", [4.0, 4.5]), extra)
    assert kept.stage == "stacked" and "shorter than the prioritised plan (5.00 s)" in kept.coordination
    assert extra["stacked"].endswith("4.50 s, kept")
    assert stacked_beside(prioritised, _stage("stacked", [5.0]), {}).stage == "prioritised"  # a tie
    assert stacked_beside(prioritised, None, {}) is prioritised
