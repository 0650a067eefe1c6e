"""Fixtures shared by the swarm layer's tests."""

from __future__ import annotations

import pytest

from proxplan.planfile import scenario_from_dict
from proxplan.planner.formations import grid_reshuffle
from proxplan.planner.swarm import SwarmOptions, swarm_problem
from proxplan.planner.swarm.levels import stacking_keepouts
from proxplan.planner.swarm.stages import plan_stages as _plan


@pytest.fixture(scope="module")
def stacked16():
    """grid-16 without prioritised planning: the stacked plan, re-timed, before any repair: (scenario,
    problem, tracks by vehicle index)."""
    sc = scenario_from_dict(grid_reshuffle(16, seed=0), label="test scenario")
    problem = swarm_problem(sc)
    strict = stacking_keepouts(problem, sc.limits, sc.field_form, ())
    # one LaCAM search, as before round 20B: with four seeds the lattice plan is the shorter here, and
    # this fixture is the stacked plan
    opts = SwarmOptions(workers=1, prioritized=False, makespan_repair=False, lattice_seeds=1)
    planned = _plan(problem, 1.0, opts, False, lambda: strict, progress=None, deadline=None)
    assert planned.stage.stage == "stacked"
    return sc, problem, dict(planned.tracks)
