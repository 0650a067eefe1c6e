"""Interchangeable vehicles giving way are tried before prioritised planning (issue 37 item 5, round 25S):
where they give a plan within ``SwarmOptions.enough_factor`` of the straight-line lower bound, prioritised
planning is not run (pillar-64 by type: its 329 plannings gave up before the passing plan was found);
elsewhere prioritised planning runs as before and the early attempt says it gave up. Every plan kept
passes the verifier and is the same on every run."""

from __future__ import annotations

from dataclasses import replace

import pytest

from proxplan.planner.sampling.ordering import lower_bound_makespan_s
from proxplan.planner.swarm import SwarmOptions, swarm_timed
from proxplan.planner.timing import assemble_plan
from proxplan.verify import verify_plan

from .test_swarm_by_type_passes import _assigned

OPTIONS = SwarmOptions(workers=1, reserve_starts=False)  # as the pipeline plans by type


@pytest.fixture(scope="module")
def pillar10():
    # pillar-10 since round 27S: with the faster arcs (timing.path_law) pillar-12's early attempt gives up
    # (1.15 B after prioritised planning; 1.22 B before, by the early attempt)
    scenario, _, _ = _assigned("pillar", 10)
    return scenario, lower_bound_makespan_s(scenario)


def _key(paths) -> list:
    return sorted((name, round(p.duration_s, 9), len(p.segments)) for name, p in paths.items())


def test_a_passing_plan_within_the_factor_is_kept_without_prioritised_planning(pillar10):
    """pillar-10 by type: the vehicles giving way arrive within 1.3x the bound (1.09 B when written), so
    prioritised planning is not run (no record of it); the plan passes the verifier, lies within the
    factor, and a second run gives the same plan."""
    scenario, bound = pillar10
    paths, info = swarm_timed(scenario, OPTIONS)
    assert info.prioritised is None
    assert "pass together" in info.coordination
    assert info.makespan_s < OPTIONS.enough_factor * bound
    assert verify_plan(assemble_plan(scenario, paths, method="swarm", notes=[]), scenario) == []
    again, _ = swarm_timed(scenario, OPTIONS)
    assert _key(again) == _key(paths)


def test_without_the_factor_prioritised_planning_runs_first_and_the_same_plan_is_kept(pillar10):
    """``enough_factor=None``: prioritised planning runs first (its record is there), the vehicles giving way
    after it; the shorter kept is the same passing plan as with the factor."""
    scenario, _ = pillar10
    first, _ = swarm_timed(scenario, OPTIONS)
    paths, info = swarm_timed(scenario, replace(OPTIONS, enough_factor=None))
    assert info.prioritised is not None
    assert "within" not in (info.yielding or "")
    assert _key(paths) == _key(first)


def test_a_factor_no_plan_can_meet_leaves_prioritised_planning_to_run_and_says_so(pillar10):
    """With a factor of 1 (a plan arriving before the lower bound: none exists) the early attempt gives
    up and says so, prioritised planning runs, and the plan kept still passes the verifier."""
    scenario, _ = pillar10
    paths, info = swarm_timed(scenario, replace(OPTIONS, enough_factor=1.0))
    assert info.prioritised is not None
    assert info.yielding is not None and info.yielding.startswith("within 1x the bound, before prioritised planning:")
    early = info.yielding.split("; shorter line yields")[0]
    assert "gave up" in early
    assert verify_plan(assemble_plan(scenario, paths, method="swarm", notes=[]), scenario) == []


def test_joint_moves_are_told_apart_by_their_labels():
    """The passing stage keeps each joint move's conflict-free verdict under its members and label
    (``pass_moves._free``, in ``problem.static_memo``): within a component no two joint moves share a label, and
    the kept verdict is the one computed afresh."""
    from proxplan.planner.swarm.pass_moves import _free, conflict_components, conflict_free, joint_moves
    from proxplan.planner.swarm.straight import straight_step_conflicts

    _, _, problem = _assigned("grid", 16)
    comps = conflict_components([(i, j) for i, j in straight_step_conflicts(problem) if i != j])
    assert comps
    for comp in comps:
        moves = joint_moves(problem, comp, checked=False)
        labels = [jm.label for jm in moves]
        assert len(labels) == len(set(labels))
        for jm in moves[:4]:
            assert _free(problem, jm) == conflict_free(problem, jm)
