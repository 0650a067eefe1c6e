"""Conflicting vehicles pass together (proxplan.planner.swarm.passes, issue 37 item 5, round 23S): each
group of conflicting straight lines flies one joint manoeuvre, the others their straight lines; the plan
is conflict-free, passes the verifier and is the same on every run; where none is found the stage says
it gave up."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.planfile import scenario_from_dict
from proxplan.planner.formations import layout_doc
from proxplan.planner.swarm.give_way import yielding_candidate
from proxplan.planner.swarm.goals import apply_assignment
from proxplan.planner.swarm.joint import place_joint
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.pass_moves import conflict_components, joint_moves
from proxplan.planner.swarm.passes import passing_stage
from proxplan.planner.swarm.prioritised_stage import horizon_steps
from proxplan.planner.swarm.problem import swarm_problem
from proxplan.planner.swarm.straight import own_straight_track, straight_step_conflicts
from proxplan.planner.swarm.tracks import GRID_DT_S
from proxplan.planner.swarm.yielding import yielding_stage
from proxplan.planner.timing import assemble_plan
from proxplan.planner.timing.arcs import ArcMove
from proxplan.verify import verify_plan

from .test_swarm_by_type_yielding import assert_lines_unless_yielding


def _assigned(layout: str, n: int):
    scenario, record = apply_assignment(scenario_from_dict(layout_doc(layout, n, assign="by_type"), label="test"))
    assert record is not None
    return scenario, float(record["lower_bound_s"]), swarm_problem(scenario)


@pytest.fixture(scope="module")
def grid16():
    return _assigned("grid", 16)


def test_conflict_components_are_the_connected_groups_of_the_pairs():
    """Union of pairs sharing a vehicle, each group sorted, in order of its smallest vehicle."""
    assert conflict_components([(5, 6), (1, 0), (2, 1), (9, 7), (6, 8)]) == [(0, 1, 2), (5, 6, 8), (7, 9)]
    assert conflict_components([]) == []


def test_a_head_on_swap_passes_with_both_bulging_half_aside(grid16):
    """grid-16 by type: for a pair of neighbours swapping slots head-on, the shortest joint move has both
    on arcs bulging to the same hand (opposite sides, seen from above), conflict-free with each other;
    it is shorter than one of them bulging the whole reach while the other keeps its line."""
    _, _, problem = grid16
    pairs = [(i, j) for i, j in straight_step_conflicts(problem) if i != j]
    s, g = problem.starts_m, problem.goals_m
    swaps = [(i, j) for i, j in pairs if np.allclose(s[i], g[j]) and np.allclose(s[j], g[i])]
    assert swaps, "grid-16 by type has a head-on swap of neighbours"
    comp = next(c for c in conflict_components(pairs) if set(swaps[0]) <= set(c))
    moves = joint_moves(problem, comp)
    assert moves
    best = moves[0]
    assert "on its line" not in best.label
    swap = [best.moves[comp.index(a)] for a in swaps[0]]
    assert all(len(legs) == 1 and isinstance(legs[0][1], ArcMove) for legs in swap)
    i, j = swaps[0]
    bulge_i, bulge_j = (best.moves[comp.index(a)][0][1].bulge for a in (i, j))
    assert float(np.dot(bulge_i, bulge_j)) < 0.0  # opposite sides of the common line
    tracks = best.tracks(problem, 0)
    occ = Occupancy(problem, tracks, best.steps + 2)
    assert all(not occ.conflicting_agents(tr) for tr in tracks)
    left = np.array([-(g[i] - s[i])[1], (g[i] - s[i])[0], 0.0])
    whole = ArcMove(s[i], g[i], problem.reach_xy_m * left / np.linalg.norm(left), problem.limits[i], GRID_DT_S)
    assert best.steps < whole.steps


def test_the_joint_move_is_placed_at_the_earliest_common_departure(grid16):
    """Against the others' straight lines, ``place_joint`` returns a departure at which every member's
    track is conflict-free with them, and none earlier is."""
    _, bound, problem = grid16
    pairs = [(i, j) for i, j in straight_step_conflicts(problem) if i != j]
    placed = []
    for comp in conflict_components(pairs):
        others = [own_straight_track(problem, a) for a in range(problem.n_agents) if a not in comp]
        occ = Occupancy(problem, others, horizon_steps(bound))
        for jm in joint_moves(problem, comp):
            d = place_joint(occ, jm)
            if d is not None:
                placed.append((occ, jm, d))
    assert placed
    occ, jm, d = max(placed, key=lambda x: x[2])  # the latest departure: the most earlier steps refused
    assert all(not occ.conflicting_agents(tr) for tr in jm.tracks(problem, d))
    for earlier in range(d):
        assert any(occ.conflicting_agents(tr) for tr in jm.tracks(problem, earlier))


def test_passing_together_is_conflict_free_verifies_and_beats_yielding_one_by_one(grid16):
    """grid-16 by type: the vehicles in no conflict fly their straight lines from t = 0; no two tracks
    conflict; the plan passes the verifier; where the shorter line of each pair yielding gives up
    (rotations of three on a 0.6 m lattice, round 20S) the vehicles passing together find a plan, shorter
    than every vehicle in a conflict keeping right one by one."""
    scenario, bound, problem = grid16
    pairs = straight_step_conflicts(problem)
    got = passing_stage(problem, horizon_steps(bound), pairs)
    assert got.stage is not None, got.note
    tracks = got.stage.tracks
    assert_lines_unless_yielding(got, problem)
    timed = {problem.names[tr.agent]: tr.timed_path() for tr in tracks}
    assert verify_plan(assemble_plan(scenario, timed, method="swarm", notes=[]), scenario) == []
    assert yielding_stage(problem, horizon_steps(bound)).stage is None
    right = yielding_stage(problem, horizon_steps(bound), right_hand=True).stage
    assert right is not None  # 1.86 B when written, against 1.47 B passing together
    assert max(tr.arrival_s for tr in tracks) < max(tr.arrival_s for tr in right.tracks)


def test_the_same_problem_gives_the_same_plan(grid16):
    """Budgets are counts: two runs give the same tracks (moves, departures, arrivals)."""
    _, bound, problem = grid16
    pairs = straight_step_conflicts(problem)

    def key(result):
        return [
            (tr.agent, tr.arrival_step, [(k, type(mv).__name__, mv.steps) for k, mv in tr.moves])
            for tr in result.stage.tracks
        ]

    assert key(passing_stage(problem, horizon_steps(bound), pairs)) == key(
        passing_stage(problem, horizon_steps(bound), pairs)
    )


def test_asked_for_a_plan_shorter_than_it_can_find_the_stage_says_it_gave_up(grid16):
    """With every vehicle to arrive before the bound B (no plan can), the stage returns no plan and
    says it gave up; it never returns a plan it did not find."""
    _, bound, problem = grid16
    got = passing_stage(problem, horizon_steps(bound), straight_step_conflicts(problem), arrive_by=1)
    assert got.stage is None
    assert got.note.startswith("gave up after")


def test_the_candidate_tries_passing_together_first_and_only_where_asked(grid16):
    """``yielding_candidate`` reports the vehicles passing together first; inside the stacked plan's
    levels (``together=False``) it does not try them."""
    _, bound, problem = grid16
    extra: dict = {}
    got = yielding_candidate(problem, horizon_steps(bound), extra)
    assert got is not None and extra["yielding"].startswith("pass together:")
    extra_level: dict = {}
    yielding_candidate(problem, horizon_steps(bound), extra_level, together=False)
    assert "pass together" not in extra_level["yielding"]


@pytest.mark.slow
def test_grid64_by_type_through_the_swarm_layer_passes_together_and_verifies():
    """grid-64 by type: the plan kept is the vehicles passing together, it passes the verifier and is
    below 1.45 B (1.32 B when written; 1.63 B before, prioritised planning's detours, round 23S)."""
    from proxplan.planner.swarm import SwarmOptions, swarm_timed

    scenario, bound, _ = _assigned("grid", 64)
    paths, info = swarm_timed(scenario, SwarmOptions(workers=1, reserve_starts=False))
    assert "pass together" in info.coordination
    assert info.makespan_s < 1.45 * bound
    assert verify_plan(assemble_plan(scenario, paths, method="swarm", notes=[]), scenario) == []
