"""Prioritised planning's count budget where the goals were assigned (``assign_goals: by_type``; issue 37
item 5, round 24S).

There the vehicles passing together and yielding (:mod:`~proxplan.planner.swarm.give_way`) give the plan
on most layouts, and a pass of prioritised planning either plans each vehicle once or gives up: on the named
layouts at 64 by type every pass that found a plan made one planning per vehicle and no repair (grid 65 and 64,
circle 64 and 64, corridor 64 and 64 plannings in the two orders), while pillar-64's passes gave up after 137
and 192 plannings (329 in all, 13.9 s of its 20 s of CPU) before another stage gave the plan
(docs/planner.md, stop 62 round 24S). So each order is given one planning per vehicle and its share of
repairs (``SwarmOptions.repairs_per_vehicle``): :func:`assigned_budget`, 2.5 per vehicle with the defaults
against ``SwarmOptions.plannings_per_vehicle`` (6) with fixed goals. A count: the same plan on every machine.
"""

from __future__ import annotations

import math

from proxplan.planner.swarm.options import SwarmOptions
from proxplan.planner.swarm.problem import SwarmProblem

__all__ = ["assigned_budget"]


def assigned_budget(problem: SwarmProblem, opts: SwarmOptions) -> int:
    """Single-vehicle plannings of prioritised planning over all its passes where the goals were assigned:
    per order of ``opts.orders``, one per vehicle and ``opts.repairs_per_vehicle`` more (see module), never
    more than its budget with fixed goals (``opts.plannings_per_vehicle`` per vehicle)."""
    per_vehicle = min(len(opts.orders) * (1.0 + opts.repairs_per_vehicle), opts.plannings_per_vehicle)
    return math.ceil(per_vehicle * problem.n_agents)
