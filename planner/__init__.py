"""Multi-vehicle planning, by role (sub-packages in data-flow order, each importing only the ones
before it):

- :mod:`proxplan.planner.timing`: Ruckig segments, timed paths, the common time grid of plan.json;
- :mod:`proxplan.planner.checks`: constraint rules (separation, downwash cut-offs, ellipsoid,
  tracking tube), their vectorised form and the checks of a scenario before any search;
- :mod:`proxplan.planner.sampling`: the single-vehicle OMPL space-time planner and prioritised
  planning with it;
- :mod:`proxplan.planner.swarm`: swarms - goal assignment, joint coordination on a lattice with
  exact synchronous conflicts (LaCAM), continuous-time planning and re-timing (``method="swarm"``,
  and ``"optimized"`` for swarms);
- :mod:`proxplan.planner.optimizer`: CasADi refinement keeping predicted wrenches within authority.

:mod:`proxplan.planner.bounds` gives certified makespan lower bounds (straight line, round obstacles,
throughput through an obstacle's slab; :func:`certified_bound`).

At the top level, :mod:`proxplan.planner.pipeline` runs them (pre-checks, planner, verifier safety
net, refinement, metrics); the independent verifier (package ``verify``) checks every plan it
returns. :mod:`~proxplan.planner.compare` runs every method on the shipped scenarios and
:mod:`~proxplan.planner.formations` generates swarm scenarios (both ``python -m``).
"""

from proxplan.planner.bounds import CertifiedBound, certified_bound
from proxplan.planner.errors import InfeasibleError, PlanNotFound
from proxplan.planner.optimizer import RefineOptions, RefineResult, refine_plan
from proxplan.planner.pipeline import DT_S, METHODS, plan_scenario
from proxplan.planner.plot import plot_plan
from proxplan.planner.summary import plan_summary
from proxplan.planner.timing import common_grid, time_parameterize

__all__ = [
    "CertifiedBound",
    "DT_S",
    "METHODS",
    "InfeasibleError",
    "PlanNotFound",
    "certified_bound",
    "RefineOptions",
    "RefineResult",
    "plan_scenario",
    "plan_summary",
    "plot_plan",
    "refine_plan",
    "common_grid",
    "time_parameterize",
]
