"""Multi-vehicle planning: prioritised space-time sampling with OMPL against moving downwash
sources (cut-off maps), CasADi refinement keeping predicted wrenches within authority, Ruckig
timing; the independent verifier (package ``verify``) checks every plan it returns.
"""

from planner.errors import InfeasibleError
from planner.optimize import RefineOptions, RefineResult, refine_plan
from planner.pipeline import DT_S, METHODS, plan_scenario
from planner.plot import plot_plan
from planner.summary import plan_summary
from planner.timing import common_grid, time_parameterize

__all__ = [
    "DT_S",
    "METHODS",
    "InfeasibleError",
    "RefineOptions",
    "RefineResult",
    "plan_scenario",
    "plan_summary",
    "plot_plan",
    "refine_plan",
    "common_grid",
    "time_parameterize",
]
