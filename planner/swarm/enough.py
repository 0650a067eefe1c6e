"""The bound the enough factor of interchangeable vehicles multiplies (``SwarmOptions.enough_factor``;
round 30B).

Where goals were assigned, the vehicles giving way are asked first for a plan within ``enough_factor`` of a
bound (:func:`~proxplan.planner.swarm.stages.plan_stages`); issue 37's target is 1.3x the assignment's
bound B, which weighs the way round the obstacles. The straight-line bound alone (every vehicle on its
line) is below B where a line passes through an obstacle: corridor-64 by type 1.75 s against B = 2.05 s,
so the early candidate was asked for 2.25 s (1.10 B) and gave up, and prioritised planning and the passing
stage ran again. :func:`enough_bound_s` is the larger of the straight-line bound and the certified
single-vehicle bound (:func:`~proxplan.planner.bounds.vehicle_bound_s`: through the obstacles' free
windows) of each vehicle whose line leaves the static free space: a certified bound as well (no plan is
shorter), so prioritised planning can still shorten a plan within the factor of it by at most that factor.
"""

from __future__ import annotations

from proxplan.planfile import Scenario
from proxplan.planner.bounds import vehicle_bound_s
from proxplan.planner.swarm.problem import SwarmProblem

__all__ = ["enough_bound_s"]


def enough_bound_s(scenario: Scenario, problem: SwarmProblem, lower_bound_s: float) -> float:
    """The larger of ``lower_bound_s`` (the straight-line bound, s) and the certified bound of each vehicle
    of ``problem`` (names as in ``scenario``) whose straight line leaves the static free space (see module),
    s; ``lower_bound_s`` where goals were not assigned or no line does."""
    if scenario.assign_goals is None or not scenario.obstacles:
        return lower_bound_s
    cache: dict = {}
    through = [
        problem.names[a]
        for a in range(problem.n_agents)
        if not problem.pinned[a] and not problem.segment_free(problem.starts_m[a], problem.goals_m[a])
    ]
    return max([lower_bound_s] + [vehicle_bound_s(scenario, name, cache)[0] for name in through])
