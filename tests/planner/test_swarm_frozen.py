"""Frozen pairs and the unfreeze step (proxplan.planner.swarm.frozen, issue 37 round 19C): starts or
goals clear at rest but inside the keep-out once either vehicle moves can never be left or reached under
the swarm layer's keep-outs; a short move away first (and back last) makes the plan, which the
verifier passes."""

from __future__ import annotations

import copy

import numpy as np
import pytest

from proxplan.planfile import scenario_from_dict
from proxplan.planner.formations import grid_reshuffle, random_formation
from proxplan.planner.swarm import SwarmOptions, swarm_problem, swarm_timed
from proxplan.planner.swarm.frozen import frozen_pairs, plan_unfreeze, unfrozen_problem
from proxplan.planner.timing import assemble_plan
from proxplan.verify import verify_plan

SHIFT_M = np.array([3.0, 0.0, 0.0])  # the goals: the three starts moved 3 m along x (the same triangle)


@pytest.fixture(scope="module")
def triangle():
    """Three large quads as in the family's random-3-64 (seed 3; its workspace and limits): v001 0.716 m
    above v012 and v014, each at a horizontal distance halfway between the pair's keep-out at rest and
    its keep-out while moving (random-3-64: 0.584 m between 0.565 and 0.587 m), on two sides of it; the
    goals the same triangle 3 m along x (frozen too)."""
    doc = copy.deepcopy(random_formation(64, seed=3))
    doc["vehicles"] = {k: doc["vehicles"][k] for k in ("v001", "v012", "v014")}
    top = np.array([-1.0, -2.1, 1.716])
    problem = swarm_problem(scenario_from_dict(doc, label="probe"))
    ko = problem.keepouts[(0, 0)]
    dz = np.array([0.0, 0.0, -0.716])
    rest, move = (
        min(r for r in np.arange(0.3, 1.0, 1e-4) if not ko.conflict((dz + [r, 0, 0])[None], rest=rest_)[0])
        for rest_ in (True, False)
    )
    assert move > rest, "the tube grows the keep-out"
    r = 0.5 * (rest + move)
    where = {"v001": top, "v012": top + dz + [-r, 0.0, 0.0], "v014": top + dz + [0.0, -r, 0.0]}
    for k, v in doc["vehicles"].items():
        v["start"] = where[k].round(4).tolist()
        v["goal"] = (where[k] + SHIFT_M).round(4).tolist()
    return scenario_from_dict(doc, label="frozen triangle")


def test_frozen_pairs_found_at_starts_and_goals(triangle):
    problem = swarm_problem(triangle)
    names = problem.names
    for points in (problem.starts_m, problem.goals_m):
        got = {(names[a], names[b]) for a, b in frozen_pairs(problem, points)}
        assert got == {("v001", "v012"), ("v001", "v014")}
        for a, b in frozen_pairs(problem, points):  # clear at rest, in conflict while moving
            ko = problem.keepouts[(int(problem.type_index[a]), int(problem.type_index[b]))]
            d = (points[b] - points[a])[None]
            assert not ko.conflict(d, rest=True)[0] and ko.conflict(d)[0]


def test_unfreeze_moves_one_vehicle_away_to_a_point_nothing_is_frozen_at(triangle):
    problem = swarm_problem(triangle)
    unfreeze, why = plan_unfreeze(problem, "starts")
    assert unfreeze is not None, why
    assert [problem.names[a] for a in unfreeze.movers] == ["v001"]
    moved = unfreeze.points_m - problem.starts_m
    assert np.count_nonzero(np.abs(moved).sum(axis=1)) == 1 and moved[0, 2] == 0.0  # horizontal, v001 only
    assert 0.0 < float(np.linalg.norm(moved[0])) <= problem.reach_xy_m
    assert frozen_pairs(problem, unfreeze.points_m) == []
    for b in (1, 2):  # farther from both partners, and clear of them while moving
        assert np.linalg.norm(unfreeze.points_m[b] - unfreeze.points_m[0]) > np.linalg.norm(
            problem.starts_m[b] - problem.starts_m[0]
        )
        ko = problem.keepouts[(int(problem.type_index[0]), int(problem.type_index[b]))]
        assert not ko.conflict((unfreeze.points_m[b] - unfreeze.points_m[0])[None])[0]


def test_unfrozen_plan_starts_and_ends_where_the_scenario_says_and_passes_verify(triangle):
    timed, info = swarm_timed(triangle, SwarmOptions(workers=1))
    assert "frozen pairs at the starts" in info.coordination and "frozen pairs at the goals" in info.coordination
    for name, path in timed.items():
        np.testing.assert_allclose(path.knot_p_m[0], triangle.vehicles[name].start_m, atol=1e-9)
        np.testing.assert_allclose(path.knot_p_m[-1], triangle.vehicles[name].goal_m, atol=1e-9)
    assert info.makespan_s == pytest.approx(max(p.duration_s for p in timed.values()))
    plan = assemble_plan(triangle, timed, method="swarm", notes=[])
    assert verify_plan(plan, triangle) == []


def test_nothing_frozen_leaves_the_problem_as_it_is():
    problem = swarm_problem(scenario_from_dict(grid_reshuffle(16, seed=0), label="grid-16"))
    out, unfreezes, note = unfrozen_problem(problem)
    assert out is problem and unfreezes == () and note == ""
