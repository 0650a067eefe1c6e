"""The single-vehicle sampling planner and the prioritised planning built on it.

One vehicle is searched in space-time (x, y, z, t) with OMPL's RRT against the vehicles planned
before it (:func:`plan_space_time`; a small earliest-arrival roadmap with waits is tried first,
:mod:`~proxplan.planner.sampling.roadmap`); :func:`sampling_plan` plans every vehicle of a scenario
one after another in :func:`priority_order`, times each path with Ruckig, re-checks it and
re-orders on failure (:func:`promote`).

Modules: :mod:`~proxplan.planner.sampling.spec` (goal, options, result),
:mod:`~proxplan.planner.sampling.space_time` (the OMPL planner),
:mod:`~proxplan.planner.sampling.termination` (deterministic termination and seeding),
:mod:`~proxplan.planner.sampling.roadmap` (waits roadmap), :mod:`~proxplan.planner.sampling.ordering`
(priority order, promotion, lower bound), :mod:`~proxplan.planner.sampling.prioritized` (the
per-vehicle loop).
"""

from proxplan.planner.sampling.ordering import lower_bound_makespan_s, priority_order, promote
from proxplan.planner.sampling.prioritized import PLAN_MARGIN_M, sampling_plan
from proxplan.planner.sampling.space_time import plan_space_time, start_conflict
from proxplan.planner.sampling.spec import GoalSpec, SamplingOptions, SpaceTimePath

__all__ = [
    "PLAN_MARGIN_M",
    "GoalSpec",
    "SamplingOptions",
    "SpaceTimePath",
    "lower_bound_makespan_s",
    "plan_space_time",
    "priority_order",
    "promote",
    "sampling_plan",
    "start_conflict",
]
