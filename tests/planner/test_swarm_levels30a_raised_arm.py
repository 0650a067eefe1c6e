"""The raised arm of prioritised planning on a level (round 30A): on a top or bottom level of the stacked plan
with room above, the passes are planned flat and again with routes raised (swarm.raised), within a count
of plannings, and the shorter plan kept, ties the flat one: never longer than the flat passes alone; not
tried where the flat plan arrives at the bound, nor on a level with no room above."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from proxplan.planfile import scenario_from_dict
from proxplan.planner.swarm import SwarmOptions, swarm_problem
from proxplan.planner.swarm.prioritised_stage import prioritised_stage, raised_arm
from proxplan.planner.swarm.stacked import alone_steps
from proxplan.planner.swarm.tracks import GRID_DT_S


def _line_level(top_m: float = 3.0, half_width_m: float = 0.45):
    """Three Crazyflies on one line at 1.5 m, the box's floor cut to that height (a top level of the stacked
    plan, :func:`~proxplan.planner.swarm.stacked.level_subproblem`), ``half_width_m`` either side of the line
    (0.45 m: no room to pass beside at one height): ``far`` (6 m) through the starts and goals of ``near`` and ``mid``, which
    fly the other way."""
    doc = {
        "name": "line-level",
        "workspace": {"min": [-4.0, -half_width_m, 0.0], "max": [4.0, half_width_m, top_m]},
        "limits": {"authority_fraction": 0.1, "min_separation_m": 0.25},
        "vehicles": {
            "far": {"type": "crazyflie-2.1", "start": [-3.0, 0.0, 1.5], "goal": [3.0, 0.0, 1.5]},
            "near": {"type": "crazyflie-2.1", "start": [1.0, 0.0, 1.5], "goal": [-1.0, 0.0, 1.5]},
            "mid": {"type": "crazyflie-2.1", "start": [2.0, 0.0, 1.5], "goal": [-2.0, 0.0, 1.5]},
        },
    }
    problem = swarm_problem(scenario_from_dict(doc, label="test scenario"))
    lo = problem.lo_m.copy()
    lo[2] = 1.5 - 1e-3
    return replace(problem, lo_m=lo)


def _bound_s(problem) -> float:
    return alone_steps(problem) * GRID_DT_S


def _plan(problem, **changes):
    opts = replace(SwarmOptions(workers=1, reserve_starts=True), **changes)
    extra: dict = {}
    got = prioritised_stage(problem, _bound_s(problem), opts, extra, progress=None, deadline=None)
    return got, extra


def _makespan_steps(stage) -> int:
    return max(tr.arrival_step for tr in stage.tracks)


def test_the_raised_arm_only_on_a_level_with_room_above():
    problem = _line_level()
    assert raised_arm(problem, SwarmOptions())
    assert not raised_arm(problem, SwarmOptions(raised_routes=False))
    hi = problem.hi_m.copy()
    hi[2] = 1.5 + 1e-3  # cut to the level's height: a bottom level's vehicles sit at its band's top
    assert not raised_arm(replace(problem, hi_m=hi), SwarmOptions())


def test_where_no_flat_pass_plans_the_raised_arm_does():
    problem = _line_level()
    flat, _ = _plan(problem, raised_routes=False)
    got, extra = _plan(problem)
    assert flat is None
    assert got is not None and "routes raised" in got.coordination
    assert extra["counts"]["raised_planned"] > 0


def test_never_longer_than_the_flat_passes_and_the_same_every_time():
    problem = _line_level(half_width_m=1.2)
    flat, flat_extra = _plan(problem, raised_routes=False)
    got, extra = _plan(problem)
    again, _ = _plan(problem)
    assert flat is not None and got is not None
    assert "routes raised" not in flat_extra["prioritised"]
    assert "routes raised" in extra["prioritised"]  # the raised arm was tried (or said why not)
    assert _makespan_steps(got) <= _makespan_steps(flat)
    if _makespan_steps(got) == _makespan_steps(flat):  # ties: the flat arm's plan
        for a, b in zip(got.tracks, flat.tracks, strict=True):
            np.testing.assert_array_equal(a.positions_m, b.positions_m)
    for a, b in zip(got.tracks, again.tracks, strict=True):
        np.testing.assert_array_equal(a.positions_m, b.positions_m)


def test_a_raised_arm_without_plannings_gives_the_flat_plan():
    problem = _line_level(half_width_m=1.2)
    flat, _ = _plan(problem, raised_routes=False)
    got, extra = _plan(problem, raised_plannings_per_vehicle=0.0)
    assert flat is not None and got is not None
    assert "routes raised" in extra["prioritised"]
    assert extra["counts"].get("raised_planned", 0) == 0
    for a, b in zip(got.tracks, flat.tracks, strict=True):
        np.testing.assert_array_equal(a.positions_m, b.positions_m)
