"""Where LaCAM stops on its count budget, the stacked plan is still tried (issue 37, round 19C): before,
``lattice_stage`` raised first and the stacked plan was never made."""

from __future__ import annotations

import pytest

from proxplan.planfile import scenario_from_dict
from proxplan.planner.errors import PlanNotFound
from proxplan.planner.formations import grid_reshuffle
from proxplan.planner.swarm import SwarmOptions, swarm_timed
from proxplan.planner.timing import assemble_plan
from proxplan.verify import verify_plan

# LaCAM stopped after one proposal (its budget is a count): every vehicle flies 6 m, more than a lattice
# move, so one step never reaches the goals; no prioritised planning, so the lattice stage and the
# stacked plan are what is left
STOPPED = SwarmOptions(workers=1, prioritized=False, max_proposals=1)


def _cross(types: tuple[str, str]):
    """Two vehicles of the first type fly 6 m along x, two of the second 6 m along y, their lines
    crossing: no synchronised straight step; on levels of their own (one per type) each pair flies its
    parallel lines 1.2 m apart, a straight step."""
    doc = grid_reshuffle(4, seed=0)
    doc["workspace"] = {"min": [-4.0, -4.0, 0.0], "max": [4.0, 4.0, 3.5]}
    doc["vehicles"] = {
        "a0": {"type": types[0], "start": [-3.0, -0.6, 1.5], "goal": [3.0, -0.6, 1.5]},
        "a1": {"type": types[0], "start": [-3.0, 0.6, 1.5], "goal": [3.0, 0.6, 1.5]},
        "b0": {"type": types[1], "start": [-0.6, -3.0, 1.5], "goal": [-0.6, 3.0, 1.5]},
        "b1": {"type": types[1], "start": [0.6, -3.0, 1.5], "goal": [0.6, 3.0, 1.5]},
    }
    return scenario_from_dict(doc, label="cross")


def test_lacam_stopped_leaves_the_stacked_plan_and_it_passes_verify():
    sc = _cross(("small-quad", "crazyflie-2.1"))
    timed, info = swarm_timed(sc, STOPPED)
    assert info.stage == "stacked"
    assert "LaCAM: no plan found within 1 configuration proposals" in info.coordination
    assert verify_plan(assemble_plan(sc, timed, method="swarm", notes=[]), sc) == []


def test_lacam_stopped_without_a_stacked_plan_says_both():
    """One vehicle type: no stack of levels, so LaCAM's "not found" stands, with the stacked plan's reason."""
    with pytest.raises(PlanNotFound, match=r"within 1 configuration proposals; stacked plan: no stack"):
        swarm_timed(_cross(("small-quad", "small-quad")), STOPPED)
