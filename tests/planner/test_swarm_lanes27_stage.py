"""Two-way lanes (round 27A, docs/planner.md "Stop 65, round 27A"): the level bands of the stacked plan, and
the lane stage (swarm.lanes) on a two-way passage: every vehicle planned, conflict-free, lanes to the right of
each heading (opposite headings on opposite sides), the same plan twice."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from proxplan.planfile import scenario_from_dict
from proxplan.planner.formations import LAYOUTS
from proxplan.planner.swarm import swarm_problem
from proxplan.planner.swarm.lanes import KEEP_RIGHT, lane_routes, lanes_stage
from proxplan.planner.swarm.levels import Levels, level_bands_m
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.stacked import level_subproblem
from proxplan.planner.swarm.tracks import GRID_DT_S
from proxplan.planner.timing.profile import rest_to_rest


def test_bands_widen_only_the_outer_levels():
    bands = level_bands_m((0.7, 1.8, 2.4), 0.2, 2.8)
    assert bands == ((0.2, 0.7), (1.8, 1.8), (2.4, 2.8))
    levels = Levels(groups=((0,), (1,)), heights_m=(0.7, 1.8), agent_z_m=np.zeros(0))
    assert levels.band_m(1) == (1.8, 1.8)  # no bands given: the level's height only


def _two_way(n: int):
    """corridor-n: each column trades sides through the gap in the wall, both ways on one line."""
    return swarm_problem(scenario_from_dict(LAYOUTS["corridor"](n), label=f"corridor-{n}"))


def _bound_s(problem) -> float:
    return max(
        rest_to_rest(
            float(np.linalg.norm(problem.goals_m[a] - problem.starts_m[a])), problem.limits[a], GRID_DT_S
        ).duration_s
        for a in range(problem.n_agents)
    )


def test_level_subproblem_box_is_the_band():
    problem = _two_way(8)
    sub = level_subproblem(problem, [0, 1, 2], (1.0, 2.5))
    assert sub.n_agents == 3
    assert sub.lo_m[2] < 1.0 and sub.lo_m[2] > 0.99 and 2.5 < sub.hi_m[2] <= 2.501  # eased by 1 mm


def test_lanes_keep_opposite_headings_on_opposite_sides():
    problem = _two_way(8)
    routes, _ = lane_routes(problem, 2000, KEEP_RIGHT)
    for a, W in routes.items():
        heading = (problem.goals_m[a] - problem.starts_m[a])[:2]
        right = np.array([heading[1], -heading[0]]) / np.linalg.norm(heading)
        mid = W[1:-1] if len(W) > 2 else W
        side = (mid[:, :2] - problem.starts_m[a, :2]) @ right
        assert side.min() >= -1e-9, problem.names[a]  # never to the left of its own line


def test_lane_stage_plans_every_vehicle_without_conflict_and_the_same_twice():
    problem = _two_way(12)
    bound = _bound_s(problem)
    extra: dict = {}
    stage = lanes_stage(problem, bound, extra)
    assert stage is not None, extra["lanes"]
    horizon = max(tr.arrival_step for tr in stage.tracks) + 1
    for tr in stage.tracks:
        np.testing.assert_allclose(tr.positions_m[0], problem.starts_m[tr.agent])
        np.testing.assert_allclose(tr.positions_m[-1], problem.goals_m[tr.agent])
        others = Occupancy(problem, [t for t in stage.tracks if t.agent != tr.agent], horizon)
        assert not others.conflicting_agents(tr), problem.names[tr.agent]
    again = lanes_stage(replace(problem), bound, {})
    assert again is not None
    assert [t.arrival_step for t in again.tracks] == [t.arrival_step for t in stage.tracks]
    for t0, t1 in zip(stage.tracks, again.tracks, strict=True):
        np.testing.assert_array_equal(t0.positions_m, t1.positions_m)
