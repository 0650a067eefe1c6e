"""The stacked plan beside a prioritised plan made level by level only while it can still be shorter
(round 25A: complete_stages.BesideLevels, stacked.StackedBound): the same plans as making it whole, and
the bound is the stacked plan's makespan once its levels are planned."""

import math

import numpy as np
import pytest

from proxplan.planfile import scenario_from_dict
from proxplan.planner.formations import LAYOUTS
from proxplan.planner.swarm import SwarmOptions
from proxplan.planner.swarm import complete_stages as cs
from proxplan.planner.swarm.complete_stages import BesideLevels, join_levels, stage_makespan
from proxplan.planner.swarm.frozen import unfrozen_problem
from proxplan.planner.swarm.hand_on import level_stacking as _stacking
from proxplan.planner.swarm.levels import levelled_endpoints, stack_levels
from proxplan.planner.swarm.plan import swarm_timed
from proxplan.planner.swarm.problem import swarm_problem
from proxplan.planner.swarm.stacked import stacked_bound
from proxplan.planner.swarm.stages import level_planner as _level_planner
from proxplan.planner.swarm.tracks import GRID_DT_S


def _scenario(layout: str, n: int):
    return scenario_from_dict(LAYOUTS[layout](n), label=f"{layout}-{n}")


def _paths(timed) -> dict:
    return {name: (p.knot_t_s.tolist(), p.knot_p_m.tolist()) for name, p in timed.items()}


# circle-16: stopped before its first level; pillar-16: after its first (main made both, not kept)
@pytest.mark.parametrize(("layout", "n", "planned"), [("circle", 16, 0), ("pillar", 16, 1)])
def test_stopping_the_stacked_plan_gives_the_same_plan(monkeypatch, layout: str, n: int, planned: int) -> None:
    sc = _scenario(layout, n)
    timed, info = swarm_timed(sc, SwarmOptions())
    assert info.stage == "prioritised"
    assert info.stacked.startswith("not made beside the prioritised plan (")
    assert f"after {planned} of 2 levels planned" in info.stacked
    rival_s = float(info.stacked.split("(", 1)[1].split(" s)")[0])
    least_s = float(info.stacked.rsplit("arrives before ", 1)[1].split(" s")[0])
    assert least_s >= rival_s

    monkeypatch.setattr(cs.BesideLevels, "can_be_shorter", lambda self: True)  # made whole, as before 25A
    timed_whole, info_whole = swarm_timed(sc, SwarmOptions())
    assert _paths(timed_whole) == _paths(timed)
    assert info_whole.makespan_s == info.makespan_s and info_whole.stage == info.stage
    assert info_whole.stacked.endswith("not kept")
    made_s = float(info_whole.stacked.rsplit("): ", 1)[1].split(" s")[0])
    assert made_s >= least_s - 0.005  # the bound is below what the whole stacked plan took (2 decimals)


def test_the_bound_is_the_stacked_plans_makespan_once_its_levels_are_planned() -> None:
    """grid-16 keeps its stacked plan: with its levels' plans (the longest of L steps), the plan's makespan
    is the bound's down + max(L, alone) + up steps, and L is no shorter than the lines alone."""
    sc = _scenario("grid", 16)
    problem, _, _ = unfrozen_problem(swarm_problem(sc))
    stack = stack_levels(problem, _stacking(sc, problem)())
    assert stack is not None
    bound = stacked_bound(problem, stack)
    assert bound is not None
    record: list = []
    beside = BesideLevels(
        problem, stack, math.inf, _level_planner(SwarmOptions(), False, record, progress=None, deadline=None)
    )
    stacked = join_levels(problem, stack, {}, beside)
    assert stacked is not None and beside.planned == len(stack.groups) and beside.stopped is None
    assert beside.planned_steps >= bound.alone_steps
    assert stage_makespan(stacked) == bound.steps(beside.planned_steps) * GRID_DT_S
    lev_s, lev_g = levelled_endpoints(problem, stack)
    assert np.allclose(lev_s[:, 2], lev_g[:, 2])  # the levels are flat: the alone bound is horizontal
    stopped = BesideLevels(problem, stack, stage_makespan(stacked), beside.plan_level)
    assert not stopped.can_be_shorter() or bound.steps() * GRID_DT_S < stage_makespan(stacked)
