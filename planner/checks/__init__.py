"""Checks shared by the planners: the constraint rules of one vehicle against the others
(workspace, obstacles, separation, downwash cut-offs, keep-out ellipsoid, tracking tube), their
vectorised form for many states at once, and the checks of a scenario before any search.

Used by the sampling planner, the swarm layer and the pipeline alike, so they live in their own
sub-package below all three. Modules: :mod:`~proxplan.planner.checks.constraints` (the rules and
the scalar per-state checker), :mod:`~proxplan.planner.checks.validity` (:class:`BatchChecker`,
the same verdicts over arrays), :mod:`~proxplan.planner.checks.precheck` (swarm size, starts and
goals, goals inside a tracking tube).
"""

from proxplan.planner.checks.constraints import (
    MODES,
    ConflictChecker,
    CutoffTable,
    PairRule,
    Track,
    UsageTable,
    build_checker,
    cutoff_table,
    usage_table,
)
from proxplan.planner.checks.precheck import (
    MAX_VEHICLES,
    check_goal_loops,
    check_goal_tubes,
    check_starts_and_goals,
    check_swarm_size,
    nearest_clear_goal,
)
from proxplan.planner.checks.validity import BatchChecker

__all__ = [
    "MAX_VEHICLES",
    "MODES",
    "BatchChecker",
    "ConflictChecker",
    "CutoffTable",
    "PairRule",
    "Track",
    "UsageTable",
    "build_checker",
    "check_goal_loops",
    "check_goal_tubes",
    "check_starts_and_goals",
    "check_swarm_size",
    "cutoff_table",
    "nearest_clear_goal",
    "usage_table",
]
