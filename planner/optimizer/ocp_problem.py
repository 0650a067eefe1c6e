"""Inputs and result of the CasADi trajectory problem (:mod:`proxplan.planner.optimizer.ocp`), as typed dataclasses.

World frame, z up; positions in m, velocities in m/s, accelerations in m/s^2, times in s.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from proxplan.physics import Vehicle


@dataclass(frozen=True)
class OcpAgent:
    """One vehicle of the problem. Arrays are world frame; warm start on the n+1 grid nodes."""

    name: str
    vehicle: Vehicle
    moving: bool
    start_m: np.ndarray  # (3,)
    goal_m: np.ndarray | None = None  # (3,) absolute goal; None with dock_with or when hovering
    dock_with: str | None = None  # partner whose final position + dock_offset_m is the goal
    dock_offset_m: np.ndarray | None = None  # (3,), m
    dock_reach_m: float = 0.0  # radius around the dock point of the axis-bound final approach, m
    dock_approach_m: float = 0.0  # length of the straight final approach, approach point A to dock point D, m
    max_speed_mps: float = 1.0
    max_accel_mps2: float = 2.0
    max_jerk_mps3: float = 5.0
    body_radius_m: float = 0.1  # disc holding frame and propellers (arm + propeller radius), m
    warm_position_m: np.ndarray | None = None  # (n+1, 3)
    warm_velocity_mps: np.ndarray | None = None  # (n+1, 3)
    warm_acceleration_mps2: np.ndarray | None = None  # (n+1, 3)
    # a vehicle that is not optimised but flies a known trajectory (decomposition, proxplan.planner.optimizer.reoptimize):
    # its positions at the check points, nodes (n+1) then interval midpoints (n), shape (2n+1, 3), m
    fixed_path_m: np.ndarray | None = None
    # constant disturbance on this (fixed) vehicle from sources outside the problem's pairs at the
    # check points, rows (F_z N, tau_x N m, tau_y N m), shape (3, 2n+1); added to its authority sum
    background_wrench: np.ndarray | None = None


@dataclass(frozen=True)
class OcpWeights:
    """Objective weights: time in s, the others dimensionless per second of flight."""

    time: float = 1.0
    smoothness: float = 0.02  # on |j / j_max|^2
    exposure: float = 50.0  # on sum over motors of (delta f / headroom)^2: usage 0.1 held 1 s costs 0.5 s


@dataclass(frozen=True)
class OcpProblem:
    """Everything the OCP needs; ``wrench_functions[(source_name, target_name)]`` is a
    casadi.Function offset_m (3x1, p_target - p_source) -> (F_z N, tau_x N m, tau_y N m) per ordered
    pair of vehicle names (pairs without an entry have no interaction)."""

    agents: tuple[OcpAgent, ...]
    n_intervals: int
    warm_duration_s: float  # T of the warm start, s
    max_duration_s: float  # upper bound on T, s
    workspace_min_m: np.ndarray  # (3,)
    workspace_max_m: np.ndarray  # (3,)
    obstacles: tuple[tuple[np.ndarray, np.ndarray], ...] = ()  # ((3,) min_m, (3,) max_m) boxes
    min_separation_m: float = 0.3
    authority_fraction: float = 0.5
    wrench_functions: Mapping[tuple[str, str], Any] = field(default_factory=dict)
    weights: OcpWeights = OcpWeights()
    invalid_zone_keep_out: bool = True  # False for invalid_zone_rule "model"
    kinematic_margin: float = 0.97  # node limits are this fraction of the true ones
    dock_speed_factor: float = 0.5  # speed limit on the dock approach, fraction of max speed
    authority_margin: float = 0.9  # check-point bound is this fraction of authority_fraction
    obstacle_margin_m: float = 0.05  # clearance to boxes beyond the body radius, m
    chord_margin_m: float = 0.03  # extra clearance for the path between check points, m
    tube_m: float = 0.0  # tracking tube: authority checked with the target this much closer to the source's axis, m
    interaction_radius_m: float = 2.0  # horizontal range beyond which a pair is ignored, m
    # optional per ordered pair: dz_m (K,) -> lateral half-width (K,) m beyond which the pair's
    # wrench table is zero; authority terms are then kept only within it + extent_margin_m
    interaction_extent: Mapping[tuple[str, str], Callable] = field(default_factory=dict)
    extent_margin_m: float = 0.5
    max_iterations: int = 300
    max_cpu_time_s: float = 40.0  # IPOPT CPU limit per solve; also the wall budget of all rounds, s
    max_wall_time_s: float | None = None  # IPOPT wall-clock limit per solve (None: 2 x max_cpu_time_s), s
    hessian: str = "exact"  # IPOPT hessian_approximation: "exact" or "limited-memory"
    expand: bool = False  # SX-expand the NLP (only when every wrench function has an SX form)
    linear_solver: str = "mumps"  # IPOPT linear solver ("mumps" or "spral" in the PyPI casadi)
    fixed_duration_s: float | None = None  # solve for this T instead of a free one, s
    linearize: bool = True  # sequential linearisation of the wrench table (SX-expanded NLP)
    max_linearizations: int = 4  # solves of the sequential linearisation
    linearization_tol: float = 0.01  # stop when the usage error of the linear model is below this
    proximal_weight: float = 0.05  # weight on |O - O0|^2 (m^-2) keeping steps near the linearisation
    # docking in two phases: the last ``approach_intervals`` intervals form the final-approach phase
    # with its own free duration (every docker on its dock axis, the dock pair exempt from separation
    # and invalid zone, as in the verifier); 0: one phase (the approach where the warm start is on it)
    approach_intervals: int = 0
    # times of the warm-start nodes (n+1,), s; None: uniform over warm_duration_s
    warm_node_times_s: np.ndarray | None = None
    # per dock pair (source, target): casadi Function dz_m -> the model's largest authority usage of
    # the target within the approach's lateral band (the extrapolated near field inside the invalid
    # zone, S0 II-A, as the verifier evaluates it); bounds the dock pair on the approach phase
    dock_usage_functions: Mapping[tuple[str, str], Any] = field(default_factory=dict)

    def warm_times_s(self) -> np.ndarray:
        """Times of the warm-start nodes (n+1,), s."""
        if self.warm_node_times_s is not None:
            return np.asarray(self.warm_node_times_s, float)
        return np.linspace(0.0, self.warm_duration_s, self.n_intervals + 1)


@dataclass(frozen=True)
class OcpSolution:
    """Solver result. Trajectories map vehicle name to arrays on the n+1 nodes (jerk on n intervals)."""

    success: bool
    status: str  # IPOPT return status
    duration_s: float  # optimised T, s
    position_m: dict[str, np.ndarray]  # (n+1, 3)
    velocity_mps: dict[str, np.ndarray]  # (n+1, 3)
    acceleration_mps2: dict[str, np.ndarray]  # (n+1, 3)
    jerk_mps3: dict[str, np.ndarray]  # (n, 3)
    iterations: int
    solve_time_s: float  # wall time of IPOPT, s
    build_time_s: float  # wall time to build the problem, s
    objective: float
    node_times_s: np.ndarray | None = None  # (n+1,) times of the nodes, s; None: uniform over duration_s
    constraint_violation: float = float("nan")  # IPOPT's final constraint violation (unscaled, inf-norm)
    rounds: int = 1  # IPOPT solves (sequential linearisation rounds)

    def times_s(self) -> np.ndarray:
        """Times of the nodes (n+1,), s."""
        if self.node_times_s is not None:
            return np.asarray(self.node_times_s, float)
        n = next(iter(self.jerk_mps3.values())).shape[0]
        return np.linspace(0.0, self.duration_s, n + 1)


def scenario_fields(scenario) -> dict[str, Any]:
    """The :class:`OcpProblem` fields a scenario fixes: workspace, obstacles and limits."""
    limits = scenario.limits
    return {
        "workspace_min_m": np.asarray(scenario.workspace_min_m, float),
        "workspace_max_m": np.asarray(scenario.workspace_max_m, float),
        "obstacles": tuple((np.asarray(b.min_m, float), np.asarray(b.max_m, float)) for b in scenario.obstacles),
        "min_separation_m": float(limits.min_separation_m),
        "authority_fraction": float(limits.authority_fraction),
        "obstacle_margin_m": float(limits.obstacle_margin_m),
        "invalid_zone_keep_out": limits.invalid_zone_rule != "model",
        "tube_m": float(limits.tracking_margin_m),
    }
