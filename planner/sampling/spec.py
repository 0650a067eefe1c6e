"""What the single-vehicle space-time search is asked for (:class:`GoalSpec`), how
(:class:`SamplingOptions`) and what it returns (:class:`SpaceTimePath`). World frame, m, s."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from proxplan.physics import KinematicLimits


@dataclass(frozen=True)
class SamplingOptions:
    """Knobs of the space-time search (defaults suit the shipped scenarios)."""

    time_budget_s: float = 1.5  # CPU-time safety net per solve (x 4), s; the budget is max_iterations
    max_iterations: int = 100000  # RRT iterations per solve (deterministic termination)
    range_m: float = 0.8  # RRT extension range in (x, y, z, tau), m
    goal_bias: float = 0.15  # probability of sampling a goal state, -
    check_step_m: float = 0.04  # spatial resolution of motion checks, m
    check_step_s: float = 0.1  # temporal resolution of motion checks, s
    goal_time_step_s: float = 0.2  # spacing of candidate arrival times, s
    hold_check_step_s: float = 0.05  # resolution of goal-hold checks, s
    compress_step_s: float = 0.05  # resolution of the time-compression pass, s
    planning_speed_factor: float = 0.7  # speed bound inside the RRT search, fraction of max speed
    time_scale_factor: float = 0.5  # v_ref = this x max speed; the search's 4th axis is tau = v_ref t, -
    usage_weight_s: float = 20.0  # objective: seconds of flight time one usage-second is worth, s
    candidates: int = 2  # RRT solutions compared by the objective per attempt
    strict_search: bool = False  # RRT edges are exact Ruckig rest-to-rest segments (else linear, speed-bounded)
    direct_first: bool = True  # try straight / detour paths with a start delay before the RRT search
    direct_delay_step_s: float = 0.1  # start-delay resolution of the direct paths, s
    direct_accept_slack_s: float = 3.0  # a direct path this close to the unobstructed time skips the RRT, s
    direct_accept_ratio: float = 3.0  # (or within this factor of it), -
    dodge_m: float = 0.3  # dodge points of the waiting search beside / above / below start and goal, m
    detour_clearance_m: float = 0.15  # extra clearance of detour via points beyond an inflated obstacle, m
    max_searches: int | None = None  # single-vehicle searches in one whole plan (re-orderings too), or no cap
    # the plan is wanted only if it ends before this time, s (None: always): a vehicle whose accepted
    # track still moves at or after it stops the search (PlanNotFound): the plan's makespan, the latest
    # vehicle's, could not be shorter (the pipeline sets it to the swarm plan's makespan beside it)
    beat_s: float | None = None
    deflection_m: Mapping[str, float] = field(default_factory=dict)  # per vehicle: added to its tube, m
    # (its predicted deflection under the plan's own disturbance; the pipeline's second pass sets it)


@dataclass
class SpaceTimePath:
    """Waypoints (K, 3), m, and the times (K,), s, at which the vehicle is there (at rest)."""

    waypoints_m: np.ndarray
    times_s: np.ndarray
    info: dict = field(default_factory=dict)


@dataclass
class GoalSpec:
    """Where the search ends and what must stay valid afterwards.

    ``position_m`` (3,) is the search goal; ``tail`` is a list of further waypoints (3,) flown after
    arrival at rest-to-rest minimum time (the dock approach), during which the vehicle named
    ``tail_exempt`` (the dock target) is not checked; ``hold_until_s`` is how long the final
    position must stay valid, s.
    """

    position_m: np.ndarray
    hold_until_s: float
    tail: list[np.ndarray] = field(default_factory=list)
    tail_exempt: str | None = None
    tail_limits: KinematicLimits | None = None
