"""The :class:`proxplan.planner.optimizer.ocp_problem.OcpProblem` of a scenario, warm-started from
a plan: grid size, the docking phase, the agents with their warm start, the wrench tables of the
cost maps per vehicle-type pair and the dock pairs' approach-usage envelopes. World frame, z up;
m, s, N."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from proxplan.planner.optimizer.ocp_problem import OcpAgent, OcpProblem, scenario_fields
from proxplan.planner.optimizer.options import RefineOptions, WrenchProvider
from proxplan.planner.timing.plan_grid import moving_end_s

APPROACH_BAND_M = 0.04  # lateral band around the dock axis over which the approach usage is maximised, m
APPROACH_DZ_SAMPLES = 80  # dz samples of the approach usage envelope
APPROACH_TOLERANCE_M = 0.01  # the warm start is "on its final approach" this close to the A-D segment, m


def default_wrench_provider(source, target, scenario):
    """The differentiable wrench table of the cost maps (same numbers as proxplan.physics.disturbance)."""
    from proxplan.costmaps import pair_maps
    from proxplan.physics import ModelOptions

    form = getattr(scenario, "field_form", None)
    options = ModelOptions(field_form=form) if form else ModelOptions()
    effects = getattr(scenario, "effects", ())
    return pair_maps(source, target, options=options, effects=effects).table.casadi_function()


def table_extent(source, target, scenario):
    """dz_m -> lateral half-width (m) of the pair's wrench table (zero beyond it)."""
    from proxplan.costmaps import pair_maps
    from proxplan.physics import ModelOptions

    form = getattr(scenario, "field_form", None)
    options = ModelOptions(field_form=form) if form else ModelOptions()
    effects = getattr(scenario, "effects", ())
    return pair_maps(source, target, options=options, effects=effects).table.scale.half_width_m


def approach_usage_function(source, target, scenario, dz_max_m: float):
    """casadi Function dz_m -> the largest authority usage of ``target`` (-) at vertical distance
    dz below ``source`` (0 < dz <= dz_max_m) within ``APPROACH_BAND_M`` of the source's axis: the
    model evaluated directly (``proxplan.costmaps.pair_wrench``, base model and the scenario's
    effects; inside the invalid zone, dz < 3 L, its extrapolated near field), as the verifier
    evaluates a dock pair on its final approach. Piecewise linear in dz (``casadi.pw_lin``, SX)."""
    import casadi as ca

    from proxplan.costmaps import pair_wrench
    from proxplan.physics import ModelOptions, authority_usage

    form = getattr(scenario, "field_form", None)
    options = ModelOptions(field_form=form) if form else ModelOptions()
    dz = np.linspace(1e-3, dz_max_m, APPROACH_DZ_SAMPLES)
    radii = np.linspace(0.0, APPROACH_BAND_M, 9)
    angles = np.linspace(0.0, np.pi / 2, 7)  # X-frame target: symmetric under x -> -x, y -> -y
    rr, aa, zz = np.meshgrid(radii, angles, dz, indexing="ij")
    offsets = np.column_stack([(rr * np.cos(aa)).ravel(), (rr * np.sin(aa)).ravel(), -zz.ravel()])
    force, torque = pair_wrench(source, target, offsets, options, getattr(scenario, "effects", ()))
    usage = authority_usage(target, force, torque).reshape(rr.shape).max(axis=(0, 1))  # (K,)
    x = ca.SX.sym("dz_m")
    return ca.Function("approach_usage", [x], [ca.pw_lin(x, ca.DM(dz), ca.DM(usage))])


def approach_start_s(scenario, plan) -> float | None:
    """Time (s) from which every docking vehicle of ``plan`` stays on its final approach (within
    ``APPROACH_TOLERANCE_M`` of the segment from its approach point A to its dock point D, both
    relative to the dock partner's current position, as the verifier's dock exemption); None
    without docks."""
    starts = []
    t = np.asarray(plan.t_s, float)
    for name, task in scenario.vehicles.items():
        if task.dock_with is None:
            continue
        a_pt, d_pt = scenario.dock_geometry(name)
        base = scenario.final_position_m(task.dock_with)
        a_rel, d_rel = a_pt - base, d_pt - base
        rel = plan.vehicles[name].position_m - plan.vehicles[task.dock_with].position_m
        seg = a_rel - d_rel
        f = np.clip((rel - d_rel) @ seg / max(float(seg @ seg), 1e-12), 0.0, 1.0)
        off_segment = np.linalg.norm(rel - (d_rel + f[:, None] * seg), axis=1) > APPROACH_TOLERANCE_M
        last_off = np.flatnonzero(off_segment)
        starts.append(float(t[last_off[-1] + 1]) if last_off.size and last_off[-1] + 1 < t.size else float(t[0]))
    return max(starts) if starts else None


def n_intervals(makespan_s: float, n_moving: int, options: RefineOptions) -> int:
    """Grid size: one interval per ``interval_s`` of the warm start, capped so that the joint
    problem keeps about ``max_node_vehicles`` vehicle-nodes (IPOPT time grows fast beyond)."""
    cap = max(options.min_intervals, min(options.max_intervals, options.max_node_vehicles // max(1, n_moving)))
    return int(np.clip(math.ceil(makespan_s / options.interval_s), options.min_intervals, cap))


def task_agent(scenario, name: str, warm: tuple, *, moving: bool) -> OcpAgent:
    """The :class:`OcpAgent` of ``scenario``'s vehicle ``name``: its task's start, goal, limits and
    body, the warm start ``warm`` = (p, v, a) on the n+1 nodes (each None for a vehicle that does not
    move), and for a docking vehicle the dock fields: its partner and offset, the length of the
    straight final approach (approach point to dock point, from ``scenario.dock_geometry``) and the
    reach round the dock point within which that approach is axis-bound (the approach's length plus
    the verifier's goal tolerance, less 2 cm). A vehicle without a dock gets none (the defaults)."""
    task = scenario.vehicles[name]
    reach_m = approach_m = 0.0
    if task.dock_with is not None:
        from proxplan.verify import GOAL_TOLERANCE_M

        approach, dock = scenario.dock_geometry(name)
        approach_m = float(np.linalg.norm(approach - dock))
        reach_m = approach_m + GOAL_TOLERANCE_M - 0.02
    return OcpAgent(
        name=name,
        vehicle=task.vehicle,
        moving=moving,
        start_m=np.asarray(task.start_m, float),
        goal_m=None if task.goal_m is None else np.asarray(task.goal_m, float),
        dock_with=task.dock_with,
        dock_offset_m=None if task.dock_offset_m is None else np.asarray(task.dock_offset_m, float),
        dock_reach_m=reach_m,
        dock_approach_m=approach_m,
        max_speed_mps=task.max_speed_mps,
        max_accel_mps2=task.max_accel_mps2,
        max_jerk_mps3=task.max_jerk_mps3,
        body_radius_m=float(task.body_radius_m),
        warm_position_m=warm[0],
        warm_velocity_mps=warm[1],
        warm_acceleration_mps2=warm[2],
    )


def build_problem(
    scenario, initial_plan, *, options: RefineOptions = RefineOptions(), wrench_provider: WrenchProvider | None = None
) -> OcpProblem:
    """The :class:`proxplan.planner.optimizer.ocp_problem.OcpProblem` of ``scenario`` warm-started from ``initial_plan``."""
    provider = wrench_provider or default_wrench_provider
    T0 = moving_end_s(initial_plan) or float(initial_plan.makespan_s)
    n = n_intervals(T0, sum(not t.hover for t in scenario.vehicles.values()), options)
    t_nodes = np.linspace(0.0, T0, n + 1)
    n_approach = 0
    t_approach = approach_start_s(scenario, initial_plan)
    if t_approach is not None and 0.0 < t_approach < T0:
        # docking: the last intervals are the final-approach phase (its own free duration)
        n_approach = int(np.clip(math.ceil((T0 - t_approach) / options.interval_s), 3, max(3, n // 3)))
        t_nodes = np.concatenate(
            [np.linspace(0.0, t_approach, n - n_approach + 1), np.linspace(t_approach, T0, n_approach + 1)[1:]]
        )
    # the sampling plan flies at 100 % of the kinematic limits (Ruckig), the OCP keeps a margin
    # (OcpProblem.kinematic_margin): the warm start is the same paths slowed uniformly by
    # 1 / margin (speed x m, acceleration x m^2, jerk x m^3), which is feasible for every limit
    stretch = 1.0 / OcpProblem.kinematic_margin
    agents = []
    for name, task in scenario.vehicles.items():
        warm = initial_plan.vehicles[name].sample(t_nodes) if not task.hover else (None, None, None)
        slowed = (
            warm[0],
            None if warm[1] is None else warm[1] / stretch,
            None if warm[2] is None else warm[2] / stretch**2,
        )
        agents.append(task_agent(scenario, name, slowed, moving=not task.hover))
    cache: dict[tuple[int, int], object] = {}
    extents: dict[tuple[str, str], Callable] = {}
    wrench = {}
    tasks = scenario.vehicles
    for ns, src in tasks.items():
        for nt, tgt in tasks.items():
            if ns == nt or (src.hover and tgt.hover):
                continue
            key = (id(src.vehicle), id(tgt.vehicle))
            if key not in cache:
                cache[key] = provider(src.vehicle, tgt.vehicle, scenario)
            wrench[(ns, nt)] = cache[key]
            if wrench_provider is None and options.prune_by_table_extent:  # table is zero beyond it
                extents[(ns, nt)] = table_extent(src.vehicle, tgt.vehicle, scenario)
    dock_usage = {}
    for name, task in tasks.items():
        if task.dock_with is None or task.dock_offset_m is None:
            continue
        approach, dock = scenario.dock_geometry(name)
        partner_end = scenario.final_position_m(task.dock_with)
        dz_end, dz_start = float(dock[2] - partner_end[2]), float(approach[2] - partner_end[2])
        if abs(dz_end) < 1e-6 and abs(dz_start) < 1e-6:
            continue  # a level dock: no downwash between the pair on its approach
        upper, lower = (name, task.dock_with) if dz_end > 0 else (task.dock_with, name)
        dz_max = max(abs(dz_end), abs(dz_start)) + APPROACH_BAND_M + 0.1
        dock_usage[(upper, lower)] = approach_usage_function(
            tasks[upper].vehicle, tasks[lower].vehicle, scenario, dz_max
        )
    return OcpProblem(
        agents=tuple(agents),
        n_intervals=n,
        warm_duration_s=T0 * stretch,
        max_duration_s=T0 * stretch,
        warm_node_times_s=t_nodes * stretch,
        approach_intervals=n_approach,
        dock_usage_functions=dock_usage if wrench_provider is None else {},
        **scenario_fields(scenario),
        wrench_functions=wrench,
        interaction_extent=extents,
        weights=options.weights,
        max_cpu_time_s=options.max_cpu_time_s,
        max_iterations=options.max_iterations,
    )
