"""``optimized`` for swarms tries the swarm layer's other complete plans beside the fast one
(proxplan.planner.refine_stage): the shortest that passes ``verify`` is kept, with its SwarmInfo,
and the give-up plans are not tried again where prioritised planning gave up."""

from __future__ import annotations

from dataclasses import replace

from proxplan.planfile import scenario_from_dict
from proxplan.planner.formations import grid_reshuffle
from proxplan.planner.refine_stage import SWARM_ALTERNATIVES, _swarm_alternatives
from proxplan.planner.swarm import SwarmOptions, swarm_timed
from proxplan.planner.timing.plan_grid import assemble_plan, moving_end_s
from proxplan.verify import verify_plan

# the pipeline's options for ``optimized`` with fixed goals (3 + OPTIMIZE_EXTRA_PASSES re-timing passes), the
# levels flat: with routes raised over the others on a level (round 29A) grid-9's fast plan is the stacked
# plan, and this test is about the alternatives beside a prioritised one
OPTIONS = SwarmOptions(seed=0, passes=8, reserve_starts=True, raised_routes=False)


def _planned(scenario, options):
    timed, info = swarm_timed(scenario, options)
    return assemble_plan(scenario, timed, method="swarm", notes=[]), info


def test_the_shortest_verified_of_the_fast_plan_and_the_other_swarm_plans_is_kept():
    """grid-9 fixed: every alternative planned on its own and verified here (the definition); the
    plan kept is the shortest verified one, never longer than the fast plan, passes verify, and its
    info is that plan's; each alternative tried is said in a note."""
    scenario = scenario_from_dict(grid_reshuffle(9), label="grid-9")
    fast, info = _planned(scenario, OPTIONS)
    assert info.stage == "prioritised"
    want, want_stage = moving_end_s(fast), info.stage
    for _, fields in SWARM_ALTERNATIVES:
        plan, other = _planned(scenario, replace(OPTIONS, **fields))
        if verify_plan(plan, scenario) == [] and moving_end_s(plan) < want - 1e-9:
            want, want_stage = moving_end_s(plan), other.stage
    got, got_info = _swarm_alternatives(scenario, fast, info, OPTIONS, None, None)
    assert moving_end_s(got) == want <= moving_end_s(fast)
    assert got_info.stage == want_stage
    assert verify_plan(got, scenario) == []
    for what, _ in SWARM_ALTERNATIVES:
        assert any(n.startswith(f"optimized: {what}: ") for n in got.notes), what
    if got is not fast:
        assert got.method == "optimized" and got.verified


def test_the_give_up_plans_are_not_tried_again_where_prioritised_planning_gave_up():
    """A fast plan that is the lattice plan (prioritised planning off) gets no second give-up plan:
    only the other alternatives are tried."""
    scenario = scenario_from_dict(grid_reshuffle(9), label="grid-9")
    lattice_opts = replace(OPTIONS, prioritized=False)
    fast, info = _planned(scenario, lattice_opts)
    assert info.stage in ("lattice", "stacked")
    got, _ = _swarm_alternatives(scenario, fast, info, lattice_opts, None, None)
    give_up = [what for what, fields in SWARM_ALTERNATIVES if "prioritized" in fields]
    assert give_up and not any(n.startswith(f"optimized: {what}") for what in give_up for n in got.notes)
    assert any(n.startswith("optimized: ") for n in got.notes)  # the others were tried
    assert moving_end_s(got) <= moving_end_s(fast)
