"""The CasADi/IPOPT optimiser that refines a sampling plan into a tighter one.

:func:`refine_plan` warm-starts the joint optimal-control problem of all moving vehicles
(:func:`build_and_solve`) from the sampling plan and keeps the result only when the independent
verifier passes it and it is better; for swarms it re-optimises one vehicle at a time against the
others' fixed trajectories (:func:`reoptimize_plan`); ``optimized`` for swarms moves the vehicles
that set the makespan, with the vehicles in their way, together (:func:`joint_moves`).

Modules: :mod:`~proxplan.planner.optimizer.ocp_problem` (problem data and results),
:mod:`~proxplan.planner.optimizer.ocp` (build and solve; sampling a solution) with
:mod:`~proxplan.planner.optimizer.ocp_builder` (variables, dynamics, pairs),
:mod:`~proxplan.planner.optimizer.ocp_authority` (authority constraints),
:mod:`~proxplan.planner.optimizer.ocp_solve` (IPOPT and linearisation),
:mod:`~proxplan.planner.optimizer.ocp_warm` (warm-start repair);
:mod:`~proxplan.planner.optimizer.warm_problem` (a scenario's problem from a plan),
:mod:`~proxplan.planner.optimizer.acceptance` (solution to plan, verification, comparison),
:mod:`~proxplan.planner.optimizer.joint` and :mod:`~proxplan.planner.optimizer.refine` (the
refinement), :mod:`~proxplan.planner.optimizer.swarm_field` and
:mod:`~proxplan.planner.optimizer.reoptimize` (the decomposed optimisation) and
:mod:`~proxplan.planner.optimizer.joint_move` (``optimized`` for swarms: the vehicles that set the
makespan and those in their way optimised together).
"""

from proxplan.planner.optimizer.acceptance import solution_to_plan
from proxplan.planner.optimizer.joint_move import JointOptions, JointResult, joint_moves
from proxplan.planner.optimizer.ocp import build_and_solve, sample_solution
from proxplan.planner.optimizer.ocp_problem import OcpAgent, OcpProblem, OcpSolution, OcpWeights
from proxplan.planner.optimizer.options import RefineOptions, RefineResult
from proxplan.planner.optimizer.refine import check_final_configuration, refine_plan
from proxplan.planner.optimizer.reoptimize import ReoptOptions, ReoptResult, reoptimize_plan
from proxplan.planner.optimizer.warm_problem import build_problem, default_wrench_provider
from proxplan.planner.timing import moving_end_s

__all__ = [
    "JointOptions",
    "JointResult",
    "OcpAgent",
    "OcpProblem",
    "OcpSolution",
    "OcpWeights",
    "RefineOptions",
    "RefineResult",
    "ReoptOptions",
    "ReoptResult",
    "build_and_solve",
    "build_problem",
    "check_final_configuration",
    "default_wrench_provider",
    "joint_moves",
    "moving_end_s",
    "refine_plan",
    "reoptimize_plan",
    "sample_solution",
    "solution_to_plan",
]
