"""Round 30B: lines through an obstacle timed first among themselves (``swarm.through_first``) and the bound the
early candidate's enough factor multiplies (``swarm.enough``), on corridor-64 by type's two lines through the
wall (v001 and v002 cross the gap in opposite directions) flown by a scenario of their own."""

from __future__ import annotations

import numpy as np

from proxplan.planfile import scenario_from_dict
from proxplan.planner.bounds import vehicle_bound_s
from proxplan.planner.formations import layout_doc
from proxplan.planner.sampling.ordering import lower_bound_makespan_s
from proxplan.planner.swarm.enough import enough_bound_s
from proxplan.planner.swarm.hemmed import late_track
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.problem import swarm_problem
from proxplan.planner.swarm.straight import straight_step_conflicts
from proxplan.planner.swarm.through_first import through_first

HORIZON = 400


def _gap_pair(assign: bool = False):
    doc = layout_doc("corridor", 64, assign="by_type")
    doc["vehicles"] = {n: doc["vehicles"][n] for n in ("v001", "v002")}
    if not assign:
        doc.pop("assign_goals", None)
    return scenario_from_dict(doc)


def test_lines_through_the_gap_timed_first_conflict_free():
    problem = swarm_problem(_gap_pair())
    through = {i for i, j in straight_step_conflicts(problem) if i == j}
    assert through == {0, 1}
    occ = Occupancy(problem, [], HORIZON)
    alone = {a: late_track(occ, problem, a, None) for a in through}
    # alone, each on its arc, they meet in the gap: the case the module is for
    assert Occupancy(problem, [alone[0]], HORIZON).conflicting_agents(alone[1])
    pre = through_first(problem, HORIZON, through, None)
    assert pre is not None and set(pre) == {0, 1}
    assert not Occupancy(problem, [pre[0]], HORIZON).conflicting_agents(pre[1])
    # the longer line (v001) first, on its own earliest timing; the other after it, later than alone
    assert pre[0].arrival_step == alone[0].arrival_step
    assert pre[1].arrival_step > alone[1].arrival_step
    # asked for earlier arrivals: each by that step and conflict-free, or none
    for by in (pre[1].arrival_step - 1, alone[0].arrival_step, 10):
        got = through_first(problem, HORIZON, through, by)
        if got is not None:
            assert max(tr.arrival_step for tr in got.values()) <= by
            assert not Occupancy(problem, [got[0]], HORIZON).conflicting_agents(got[1])
    assert through_first(problem, HORIZON, through, 10) is None  # nobody gets round the wall in 10 steps
    assert through_first(problem, HORIZON, {0}, None) is None  # one line: nothing to time first


def test_enough_bound_weighs_the_way_round_only_where_goals_were_assigned():
    fixed, assigned = _gap_pair(), _gap_pair(assign=True)
    lb = lower_bound_makespan_s(assigned)
    assert enough_bound_s(fixed, swarm_problem(fixed), lb) == lb
    got = enough_bound_s(assigned, swarm_problem(assigned), lb)
    want = max(vehicle_bound_s(assigned, n)[0] for n in assigned.vehicles)
    assert got == max(lb, want) and got > lb * 1.05
    assert np.isfinite(got)
