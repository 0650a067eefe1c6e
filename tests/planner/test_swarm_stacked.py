"""Vehicle types on levels of their own (proxplan.planner.swarm.levels) and the stacked plan
(proxplan.planner.swarm.stacked): the levels never conflict, the vertical steps pass the exact
pair test, the stacked tracks collide nowhere, pass the verifier and are the same for the same seed."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.planfile import scenario_from_dict
from proxplan.planner.formations import grid_reshuffle
from proxplan.planner.swarm import SwarmOptions, SyncTable, swarm_problem
from proxplan.planner.swarm.levels import free_height_m, stack_levels, stacking_keepouts, transition_steps
from proxplan.planner.swarm.lns import colliding_pairs
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.stages import plan_stages as _plan
from proxplan.planner.swarm.stages import stacked_stage as _stacked_stage
from proxplan.planner.timing import assemble_plan
from proxplan.verify import verify_plan


@pytest.fixture(scope="module")
def grid16():
    sc = scenario_from_dict(grid_reshuffle(16, seed=0), label="test scenario")
    problem = swarm_problem(sc)
    return sc, problem, stacking_keepouts(problem, sc.limits, sc.field_form, ())


def test_free_height_is_the_least_height_with_no_conflict_above_it(grid16):
    """On every type pair of grid-16: from the free height up to the box's height the keep-out holds
    no point at any horizontal distance (tested on a 5 mm grid of heights), and 5 mm below it some
    height does (or it is 0)."""
    _, problem, _ = grid16
    span = float(problem.hi_m[2] - problem.lo_m[2])
    found = 0
    for ko in problem.keepouts.values():
        f = free_height_m(ko, span)
        if f is None:
            assert ko.horizontal_radius_m(span, span) > 0.0
            continue
        found += 1
        assert all(ko.horizontal_radius_m(z, z) == 0.0 for z in np.arange(f, span, 0.005))
        if f > 0.005:
            assert ko.horizontal_radius_m(f - 0.005, f - 0.005) > 0.0
    assert found > 0


def test_levels_of_different_types_never_conflict(grid16):
    """The stack on the strict keep-outs: two levels or more, every type on one, and every pair of types
    on different levels free at their height difference (both orders), strict and the problem's own."""
    _, problem, strict = grid16
    levels = stack_levels(problem, strict)
    assert levels is not None and len(levels.groups) >= 2
    assert sorted(t for g in levels.groups for t in g) == sorted({int(t) for t in problem.type_index})
    for i, (gi, zi) in enumerate(zip(levels.groups, levels.heights_m)):
        for gj, zj in list(zip(levels.groups, levels.heights_m))[i + 1 :]:
            for a in gi:
                for b in gj:
                    for kos in (strict, problem.keepouts):
                        assert kos[(a, b)].horizontal_radius_m(zj - zi, zj - zi) == 0.0
                        assert kos[(b, a)].horizontal_radius_m(zi - zj, zi - zj) == 0.0
    z = levels.agent_z_m
    assert np.all((z >= problem.lo_m[2]) & (z <= problem.hi_m[2]))


def test_transition_steps_pass_the_pair_test_and_end_where_asked():
    """Two vehicles whose swap conflicts in one step: the steps found move one at a time, every pair of
    every step passes the synchronous test, and the last configuration is the target; a swap of
    two vehicles that can only pass through each other gives None."""
    sc = scenario_from_dict(grid_reshuffle(16, seed=0), label="test scenario")
    problem = swarm_problem(sc)
    a_start, b_start = problem.starts_m[0], problem.starts_m[1]
    pos = np.array([a_start, a_start + [0.0, 0.0, 0.5], b_start, b_start + [0.0, 0.0, 0.5]])
    sync = SyncTable(problem.keepouts, problem.type_index[:2], np.round(pos * 1000).astype(np.int64))
    steps = transition_steps(sync.conflict, (0, 2), (1, 3))
    assert steps is not None and steps[-1] == (1, 3)
    prev = (0, 2)
    for q in steps:
        assert not sync.conflict(0, prev[0], q[0], 1, prev[1], q[1])
        prev = q
    swap = np.array([a_start, b_start])
    sync2 = SyncTable(problem.keepouts, problem.type_index[:2], np.round(swap * 1000).astype(np.int64))
    assert transition_steps(sync2.conflict, (0, 1), (1, 0)) is None


def test_the_stacked_plan_collides_nowhere_verifies_and_is_reproducible(grid16):
    """grid-16, the stacked plan alone (its levels planned by the swarm layer's own stages): no pair
    of tracks collides (the occupancy's exact test), every vehicle ends at its goal, the verifier
    passes it, and planning again gives the same tracks."""
    sc, problem, strict = grid16
    opts = SwarmOptions(workers=1)
    extra: dict = {}
    stage = _stacked_stage(problem, opts, False, strict, extra, progress=None, deadline=None)
    assert stage is not None, extra.get("stacked")
    assert stage.stage == "stacked"
    tracks = stage.tracks
    for tr in tracks:
        np.testing.assert_allclose(tr.end_m, problem.goals_m[tr.agent], atol=1e-9)
    horizon = max(t.arrival_step for t in tracks) + 10
    assert colliding_pairs(Occupancy(problem, tracks, horizon), range(problem.n_agents)) == set()
    timed = {problem.names[t.agent]: t.timed_path() for t in tracks}
    assert verify_plan(assemble_plan(sc, timed, method="swarm", notes=[]), sc) == []
    again = _stacked_stage(problem, opts, False, strict, {}, progress=None, deadline=None)
    assert again is not None
    for a, b in zip(tracks, again.tracks):
        np.testing.assert_array_equal(a.positions_m, b.positions_m)


def test_the_stacked_plan_is_kept_only_when_shorter_than_the_lattice_plan(grid16):
    """Without prioritised planning (the lattice stage runs): the plan kept is the stacked one only
    when its tracks arrive earlier than the lattice plan's (then with the makespan repair: on by default
    there again, stop 59 round 21A), and never without levels."""
    _, problem, strict = grid16
    opts = SwarmOptions(workers=1, prioritized=False)
    planned = _plan(problem, 1.0, opts, False, lambda: strict, progress=None, deadline=None)
    found, initial, repair, extra = planned.stage, planned.initial_makespan_s, planned.repair, planned.extra
    lattice_alone = _plan(
        problem,
        1.0,
        SwarmOptions(workers=1, prioritized=False, levels=False),
        False,
        None,
        progress=None,
        deadline=None,
    ).stage
    assert lattice_alone.stage == "lattice"
    lattice_makespan = max(t.arrival_s for t in lattice_alone.tracks)
    if found.stage == "stacked":
        assert initial < lattice_makespan
        assert repair is not None  # the makespan repair runs on the stacked plan by default (round 21A)
    else:
        assert found.stage == "lattice" and "stacked" in extra
