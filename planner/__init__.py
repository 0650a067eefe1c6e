"""Multi-vehicle planning: prioritised space-time sampling with OMPL against moving downwash
sources (cut-off maps), CasADi refinement keeping predicted wrenches within authority, Ruckig
timing; for swarms a shared lattice roadmap with precomputed conflict sets and priority-based search
(``method="roadmap"``, :mod:`proxplan.planner.swarm_plan`); the independent verifier (package
``verify``) checks every plan it returns.
"""

from proxplan.planner.errors import InfeasibleError
from proxplan.planner.optimize import RefineOptions, RefineResult, refine_plan
from proxplan.planner.pipeline import DT_S, METHODS, plan_scenario
from proxplan.planner.plot import plot_plan
from proxplan.planner.summary import plan_summary
from proxplan.planner.timing import common_grid, time_parameterize

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
