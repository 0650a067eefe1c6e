"""The swarm layer's pass of prioritised planning with both wavefronts per vehicle
(``SwarmOptions.heights``): the shorter whole plan is kept, so the plan is never longer than the
plan without, it is the plan without to the bit when that one is kept, and the same on every run;
the pass runs in the order and hold of the plan without, within what is left of the count budget,
and not at all where prioritised planning gave up."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.planfile import scenario_from_dict
from proxplan.planner.formations import formation_change, grid_reshuffle
from proxplan.planner.swarm import SwarmOptions, swarm_timed
from proxplan.planner.timing import assemble_plan
from proxplan.verify import verify_plan


# grid-16: the plan with both wavefronts is the longer one (5.55 s against 4.03 s when written);
# pillar-16: the shorter (5.15 s against 6.88 s)
@pytest.mark.parametrize("make", [grid_reshuffle, formation_change], ids=["grid-16", "pillar-16"])
def test_the_shorter_whole_plan_is_kept_and_never_longer_than_without(make):
    scenario = scenario_from_dict(make(16), label="test scenario")
    # no stacked plan beside the prioritised plan (round 24B: on grid-16 it is the shorter, and the pass
    # with both wavefronts runs only on a prioritised plan kept)
    without_paths, without = swarm_timed(scenario, SwarmOptions(workers=1, heights=False, levels=False))
    paths, info = swarm_timed(scenario, SwarmOptions(workers=1, heights=True, levels=False))
    assert info.heights is not None and info.counts["heights_planned"] > 0
    # one pass, in the plan without's order and hold, on what is left of prioritised planning's budget
    assert info.heights.count("plannings)") == 1 and info.heights.split("(")[1].split(":")[0] in without.prioritised
    assert info.counts["charged"] + info.counts["heights_planned"] <= 6 * 16
    assert info.makespan_s <= without.makespan_s
    kept = info.heights.endswith("kept both wavefronts")
    assert kept == (info.makespan_s < without.makespan_s)
    if not kept:  # the plan without, to the bit
        for name, path in without_paths.items():
            np.testing.assert_array_equal(paths[name].knot_t_s, path.knot_t_s)
            np.testing.assert_array_equal(paths[name].knot_p_m, path.knot_p_m)
    assert verify_plan(assemble_plan(scenario, paths, method="swarm", notes=[]), scenario) == []
    if kept:  # the same plan again (counts only steer both ways)
        again, _ = swarm_timed(scenario, SwarmOptions(workers=1, heights=True, levels=False))
        for name, path in paths.items():
            np.testing.assert_array_equal(again[name].knot_p_m, path.knot_p_m)


def test_no_pass_with_both_wavefronts_where_prioritised_planning_gave_up():
    """A count budget that prioritised planning cannot finish a pass within: it gives up, the lattice
    plan is the answer, and the plan with heights on is that plan to the bit, with no planning more."""
    scenario = scenario_from_dict(grid_reshuffle(16), label="test scenario")
    tight = {"workers": 1, "plannings_per_vehicle": 0.5, "levels": False}  # the lattice plan alone
    without_paths, without = swarm_timed(scenario, SwarmOptions(heights=False, **tight))
    paths, info = swarm_timed(scenario, SwarmOptions(heights=True, **tight))
    assert without.stage == info.stage == "lattice"
    assert info.counts["heights_planned"] == 0 and "not planned" in (info.heights or "")
    for name, path in without_paths.items():
        np.testing.assert_array_equal(paths[name].knot_t_s, path.knot_t_s)
        np.testing.assert_array_equal(paths[name].knot_p_m, path.knot_p_m)
