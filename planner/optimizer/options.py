"""Options and result of the refinement (:func:`proxplan.planner.optimizer.refine.refine_plan`)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from proxplan.planfile import Plan, SolverStats
from proxplan.planner.optimizer.ocp_problem import OcpWeights

WrenchProvider = (
    Callable  # (source Vehicle, target Vehicle, scenario) -> casadi.Function offset_m -> (F_z, tau_x, tau_y)
)


@dataclass(frozen=True)
class RefineResult:
    """Result of :func:`refine_plan`: the plan to use (refined, or the initial one on failure)."""

    plan: Plan
    success: bool
    message: str
    solve_time_s: float  # IPOPT wall time, s
    iterations: int  # IPOPT iterations
    stats: SolverStats | None = None  # IPOPT statistics of the solve (stored in plan.json as ``solver``)


@dataclass(frozen=True)
class RefineOptions:
    """Tuning of the refinement; the defaults are the product's."""

    interval_s: float = 0.2  # target grid step of the OCP, s
    min_intervals: int = 20
    max_intervals: int = 80
    max_node_vehicles: int = 160  # cap on n_intervals x moving vehicles
    # keep authority terms only where the warm start is within the wrench table's lateral extent
    # (+ 0.5 m), with a second pass about the first solution; faster, but on the 8-vehicle swap
    # the relative timing moves enough that the result failed verification, so it is off
    prune_by_table_extent: bool = False
    # stop re-linearising as soon as a round passes the verifier: faster (swap of 8: 5.0 s instead of
    # 8.4 s of IPOPT) but later rounds tighten the plan (makespan 7.10 s after one round, 5.95 s after four)
    stop_when_verified: bool = False
    exact_retry_node_vehicles: int = 60  # retry a failed solve with the exact MX table up to this size
    weights: OcpWeights = OcpWeights()
    max_cpu_time_s: float = 30.0  # IPOPT time limit per solve and wall budget of the rounds, s
    max_iterations: int = 600  # IPOPT iterations per solve
    max_slowdown: float = 1.3  # largest uniform slow-down accepted to repair a kinematic breach, -
    # wall-clock budget of the whole refinement, s (plan --time-budget); the best verified plan
    # found by then is returned
    time_budget_s: float = 60.0
    # up to max_joint_vehicles moving vehicles (or any dock): the joint problem, and if it fails (no
    # docks) the decomposed optimisation (proxplan.planner.optimizer.reoptimize: one vehicle at a time, sparse pairs)
    # with the rest of the budget; more: decomposed only (on the swap of 8 it found 4.10 s where
    # the joint problem found 5.95 s, and the joint problem of 8 formation vehicles did not converge)
    max_joint_vehicles: int = 4
