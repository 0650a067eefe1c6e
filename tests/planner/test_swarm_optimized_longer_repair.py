"""``optimized`` for swarms runs the makespan repair again, longer, on the kept plan's own tracks
(proxplan.planner.refine_repair, refine_stage._repaired_longer): never longer, conflict-free, the same
plan twice, kept only when shorter and verified; the swarm layer hands its final tracks on."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from proxplan.planfile import scenario_from_dict
from proxplan.planner.formations import grid_reshuffle
from proxplan.planner.refine_repair import ROUNDS, longer_repair
from proxplan.planner.refine_stage import _repaired_longer
from proxplan.planner.swarm import SwarmOptions, swarm_timed
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.timing.plan_grid import assemble_plan, moving_end_s
from proxplan.verify import verify_plan

# the pipeline's options for ``optimized`` with fixed goals: 3 + OPTIMIZE_EXTRA_PASSES re-timing passes
OPTIONS = SwarmOptions(seed=0, passes=8, reserve_starts=True)


@pytest.fixture(scope="module")
def grid9():
    """grid-9 fixed: its fast plan (3.18 s when written) is shortened to 2.45 s by the longer repair. Planned
    without routes raised over the others on a level of the stacked plan (round 29A: with them the fast
    plan is already 2.95 s, and the longer repair shortens nothing)."""
    scenario = scenario_from_dict(grid_reshuffle(9), label="grid-9")
    timed, info = swarm_timed(scenario, replace(OPTIONS, raised_routes=False))
    return scenario, timed, info


def _samples(timed: dict) -> dict:
    end_s = max(p.duration_s for p in timed.values())
    t_s = np.arange(0.0, end_s + 0.005, 0.01)
    return {name: p.sample(t_s)[0] for name, p in timed.items()}


def test_the_hand_on_carries_the_plans_own_final_tracks(grid9):
    scenario, timed, info = grid9
    hand_on = info.hand_on
    assert hand_on is not None and hand_on.tracks is not None
    again = {hand_on.problem.names[a]: tr.timed_path() for a, tr in hand_on.tracks.items()}
    want, got = _samples(timed), _samples(again)
    assert want.keys() == got.keys()
    for name in want:
        np.testing.assert_array_equal(got[name], want[name])


def test_the_longer_repair_shortens_grid9_conflict_free_the_same_twice(grid9):
    scenario, _, info = grid9
    problem, tracks = info.hand_on.problem, info.hand_on.tracks
    before = {a: tr for a, tr in tracks.items()}
    got = longer_repair(problem, tracks)
    assert tracks == before  # the tracks handed on are not changed
    assert got.makespan_before_s == pytest.approx(max(tr.arrival_s for tr in tracks.values()))
    assert got.makespan_after_s < 0.9 * got.makespan_before_s  # 2.45 of 3.18 s when written
    assert 1 <= len(got.rounds) <= ROUNDS and not got.gave_up
    occ = Occupancy(problem, list(got.tracks.values()), max(t.arrival_step for t in got.tracks.values()) + 100)
    for a, track in got.tracks.items():
        occ.remove(a)
        assert not occ.conflicting_agents(track), a
        occ.put(track)
    timed = {problem.names[a]: tr.timed_path() for a, tr in got.tracks.items()}
    assert verify_plan(assemble_plan(scenario, timed, method="optimized", notes=[]), scenario) == []
    twice = longer_repair(problem, tracks)
    assert twice.rounds == got.rounds
    again = {problem.names[a]: tr.timed_path() for a, tr in twice.tracks.items()}
    for name, q in _samples(timed).items():
        np.testing.assert_array_equal(_samples(again)[name], q)


def test_refine_keeps_the_longer_repair_only_shorter_and_verified(grid9):
    scenario, timed, info = grid9
    fast = assemble_plan(scenario, timed, method="swarm", notes=[])
    got = _repaired_longer(scenario, fast, info, None, None)
    assert got is not fast and got.verified
    assert moving_end_s(got) < 0.9 * moving_end_s(fast)
    assert verify_plan(got, scenario) == []
    assert any(n.startswith("optimized: the makespan repair, longer: round 1:") and "kept" in n for n in got.notes)


def test_no_longer_repair_without_the_swarm_layers_tracks(grid9):
    scenario, timed, _ = grid9
    fast = assemble_plan(scenario, timed, method="swarm", notes=[])
    got = _repaired_longer(scenario, fast, None, None, None)
    assert got is fast
    assert got.notes[-1].endswith("not run (not the swarm layer's tracks)")
