"""The CasADi trajectory-optimisation problem (``Opti`` + IPOPT) of the optimised planner.

All moving vehicles are optimised jointly on one uniform time grid of ``n_intervals`` intervals over
a free common duration T (s), the makespan. Each moving vehicle is a triple integrator in the world
frame (z up) with state x = (p_m, v_mps, a_mps2) at the grid nodes and a piecewise-constant jerk
input j_mps3 per interval; multiple shooting with the exact discretisation of the integrator

    p+ = p + h v + h^2/2 a + h^3/6 j,   v+ = v + h a + h^2/2 j,   a+ = a + h j,   h = T / n

so the node states describe the continuous trajectory exactly. Hovering vehicles are constants.

Constraints (nodes k = 0..n): start at rest, goal (absolute, or the dock partner's final position
plus the dock offset) at rest; speed / acceleration / jerk limits (per axis or Euclidean, matching
the verifier); workspace box; axis-aligned box obstacles by side selection from the warm start (the
face the warm-start node is furthest outside of, per node); pairwise separation; and **authority
usage <= authority_fraction** for every vehicle: the disturbance wrench (F_z, tau_x, tau_y) on a
target from each source above it comes from the differentiable wrench table of
``costmaps.map_store`` (the same numbers as ``costmaps.disturbance``); it is summed over sources and
mapped through the inverse mixer of (S0-14) (``costmaps.authority.mixer_matrix``) to per-motor thrust
changes, each bounded by ``fraction x headroom`` in its direction (DESIGN.md section 3). That is
exactly ``authority usage <= fraction`` without a non-smooth max.

Objective: T + w_smooth * integral of |j / j_max|^2 + w_exposure * integral of the summed squared
normalised motor changes (disturbance exposure).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable, Mapping

import numpy as np

from costmaps.authority import mixer_matrix
from costmaps.vehicles import Vehicle

WrenchFunction = Callable  # casadi.Function: offset_m (3x1, p_target - p_source) -> (F_z N, tau_x N m, tau_y N m)


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
    max_speed_mps: float = 1.0
    max_accel_mps2: float = 2.0
    max_jerk_mps3: float = 5.0
    body_radius_m: float = 0.1  # disc holding frame and propellers (arm + propeller radius), m
    warm_position_m: np.ndarray | None = None  # (n+1, 3)
    warm_velocity_mps: np.ndarray | None = None  # (n+1, 3)
    warm_acceleration_mps2: np.ndarray | None = None  # (n+1, 3)


@dataclass(frozen=True)
class OcpWeights:
    """Objective weights: time in s, the others dimensionless per second of flight."""

    time: float = 1.0
    smoothness: float = 0.02  # on |j / j_max|^2
    exposure: float = 0.5  # on sum over motors of (delta f / headroom)^2


@dataclass(frozen=True)
class OcpProblem:
    """Everything the OCP needs; ``wrench_functions[(source_name, target_name)]`` per ordered pair
    of vehicle names (pairs without an entry have no interaction)."""

    agents: tuple[OcpAgent, ...]
    n_intervals: int
    warm_duration_s: float  # T of the warm start, s
    max_duration_s: float  # upper bound on T, s
    workspace_min_m: np.ndarray  # (3,)
    workspace_max_m: np.ndarray  # (3,)
    obstacles: tuple[tuple[np.ndarray, np.ndarray], ...] = ()  # ((3,) min_m, (3,) max_m) boxes
    min_separation_m: float = 0.3
    authority_fraction: float = 0.5
    wrench_functions: Mapping[tuple[str, str], object] = field(default_factory=dict)
    weights: OcpWeights = OcpWeights()
    limit_norm: str = "axis"  # "axis": per-axis limits (as Ruckig); "euclidean": norm limits
    kinematic_margin: float = 0.97  # node limits are this fraction of the true ones (between nodes)
    authority_margin: float = 0.9  # node authority bound is this fraction of authority_fraction
    obstacle_margin_m: float = 0.1  # clearance to boxes beyond the body radius (incl. chords), m
    separation_margin_m: float = 0.02  # extra separation at nodes, m
    interaction_radius_m: float = 2.0  # horizontal range beyond which a source is ignored, m
    max_iterations: int = 300
    max_cpu_time_s: float = 40.0


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


def normalised_motor_map(vehicle: Vehicle) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(A (4, 3), up_N (4,), down_N (4,)) with per-motor thrust change delta_f = A @ (F_z, tau_x, tau_y).

    The target holds hover: the mixer (S0-14) must produce (m g - F_z, -tau_x, -tau_y, 0); the change
    from hover is M^-1 (-F_z, -tau_x, -tau_y, 0). ``up_N``/``down_N`` are the headrooms of
    DESIGN.md section 3 (to f_max and to f_min), N.
    """
    inv = np.linalg.inv(mixer_matrix(vehicle))
    a = -inv[:, :3]
    hover = vehicle.hover_thrust_per_rotor_N
    up = np.full(4, vehicle.max_thrust_per_rotor_N - hover)
    down = np.full(4, hover - vehicle.min_motor_thrust_N)
    return a, up, down


def _side_constraint(point: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple[int, float]:
    """Face of the box [lo, hi] that ``point`` is furthest outside of: (axis * 2 + side, depth_m)."""
    outside = np.concatenate([lo - point, point - hi])  # (6,): -x,-y,-z faces then +x,+y,+z
    face = int(np.argmax(outside))
    return face, float(outside[face])


def build_and_solve(problem: OcpProblem, *, progress: Callable[[str], None] | None = None) -> OcpSolution:
    """Build the Opti problem, warm-start it and solve with IPOPT (``expand=True``, print_level 0)."""
    import casadi as ca

    t_build = time.perf_counter()
    n = problem.n_intervals
    agents = {a.name: a for a in problem.agents}
    opti = ca.Opti()
    T = opti.variable()
    h = T / n
    opti.subject_to(opti.bounded(0.2 * problem.warm_duration_s, T, problem.max_duration_s))
    opti.set_initial(T, problem.warm_duration_s)

    pos: dict[str, object] = {}
    vel: dict[str, object] = {}
    acc: dict[str, object] = {}
    jerk: dict[str, object] = {}
    cost = problem.weights.time * T
    margin = problem.kinematic_margin
    for a in problem.agents:
        if not a.moving:
            pos[a.name] = ca.DM(np.tile(np.asarray(a.start_m, float)[:, None], (1, n + 1)))
            continue
        X = opti.variable(9, n + 1)
        U = opti.variable(3, n)
        p, v, ac = X[0:3, :], X[3:6, :], X[6:9, :]
        pos[a.name], vel[a.name], acc[a.name], jerk[a.name] = p, v, ac, U
        # multiple shooting with the exact triple-integrator step
        p_next = p[:, :-1] + h * v[:, :-1] + h**2 / 2 * ac[:, :-1] + h**3 / 6 * U
        v_next = v[:, :-1] + h * ac[:, :-1] + h**2 / 2 * U
        a_next = ac[:, :-1] + h * U
        opti.subject_to(ca.vertcat(p[:, 1:] - p_next, v[:, 1:] - v_next, ac[:, 1:] - a_next) == 0)
        opti.subject_to(X[:, 0] == ca.vertcat(ca.DM(np.asarray(a.start_m, float)), ca.DM.zeros(6)))
        opti.subject_to(X[3:9, n] == 0)
        if a.goal_m is not None and a.dock_with is None:
            opti.subject_to(p[:, n] == ca.DM(np.asarray(a.goal_m, float)))
        # kinematic limits
        vmax, amax, jmax = (margin * a.max_speed_mps, margin * a.max_accel_mps2, margin * a.max_jerk_mps3)
        if problem.limit_norm == "euclidean":
            opti.subject_to(ca.sum1(v**2) <= vmax**2)
            opti.subject_to(ca.sum1(ac**2) <= amax**2)
            opti.subject_to(ca.sum1(U**2) <= jmax**2)
        else:
            opti.subject_to(opti.bounded(-vmax, v, vmax))
            opti.subject_to(opti.bounded(-amax, ac, amax))
            opti.subject_to(opti.bounded(-jmax, U, jmax))
        lo = np.asarray(problem.workspace_min_m, float)
        hi = np.asarray(problem.workspace_max_m, float)
        opti.subject_to(opti.bounded(ca.repmat(ca.DM(lo), 1, n + 1), p, ca.repmat(ca.DM(hi), 1, n + 1)))
        cost += problem.weights.smoothness * h * ca.sumsqr(U / a.max_jerk_mps3)
        # warm start
        wp = _warm(a.warm_position_m, a.start_m, n)
        wv = _warm(a.warm_velocity_mps, np.zeros(3), n)
        wa = _warm(a.warm_acceleration_mps2, np.zeros(3), n)
        opti.set_initial(X, np.vstack([wp.T, wv.T, wa.T]))
        wj = np.diff(wa, axis=0) / (problem.warm_duration_s / n)
        opti.set_initial(U, np.clip(wj, -jmax, jmax).T)
        # obstacles: side selection from the warm start, one linear constraint per node and box
        for lo_b, hi_b in problem.obstacles:
            infl = a.body_radius_m + problem.obstacle_margin_m
            blo = np.asarray(lo_b, float) - infl
            bhi = np.asarray(hi_b, float) + infl
            for k in range(n + 1):
                face, depth = _side_constraint(wp[k], blo, bhi)
                if depth > 3.0:  # far from this box in the warm start and cannot get there
                    continue
                axis, upper = face % 3, face >= 3
                if upper:
                    opti.subject_to(p[axis, k] >= bhi[axis])
                else:
                    opti.subject_to(p[axis, k] <= blo[axis])

    # dock boundary conditions (partner may itself be moving)
    for a in problem.agents:
        if a.moving and a.dock_with is not None:
            partner = pos[a.dock_with]
            opti.subject_to(pos[a.name][:, n] == partner[:, n] + ca.DM(np.asarray(a.dock_offset_m, float)))

    warm_pos = {a.name: (_warm(a.warm_position_m, a.start_m, n) if a.moving else
                         np.tile(np.asarray(a.start_m, float), (n + 1, 1))) for a in problem.agents}
    names = [a.name for a in problem.agents]

    # separation between every pair with at least one moving vehicle: at least min_separation_m
    # and the sum of the body radii; a dock pair may come as close as its dock offset
    for i, ni in enumerate(names):
        for nj in names[i + 1:]:
            if not (agents[ni].moving or agents[nj].moving):
                continue
            dmin = problem.separation_margin_m + max(
                problem.min_separation_m, agents[ni].body_radius_m + agents[nj].body_radius_m
            )
            for x, y in ((ni, nj), (nj, ni)):
                if agents[x].dock_with == y and agents[x].dock_offset_m is not None:
                    dmin = min(dmin, float(np.linalg.norm(agents[x].dock_offset_m)))
            dist = np.linalg.norm(warm_pos[ni] - warm_pos[nj], axis=1)
            ks = [k for k in range(n + 1) if dist[k] < dmin + problem.interaction_radius_m]
            if not ks:
                continue
            diff = pos[ni][:, ks] - pos[nj][:, ks]
            opti.subject_to(ca.sum1(diff**2) >= dmin**2)

    # authority usage <= fraction for every vehicle, summed over the sources above it
    frac = problem.authority_fraction * problem.authority_margin
    for nt in names:
        target = agents[nt]
        a_map, up, down = normalised_motor_map(target.vehicle)
        terms: dict[int, list] = {}
        for ns in names:
            fn = problem.wrench_functions.get((ns, nt))
            if ns == nt or fn is None or not (agents[ns].moving or target.moving):
                continue
            rel = warm_pos[nt] - warm_pos[ns]
            horiz = np.linalg.norm(rel[:, :2], axis=1)
            for k in range(n + 1):
                if horiz[k] > problem.interaction_radius_m:
                    continue
                w = fn(pos[nt][:, k] - pos[ns][:, k])
                terms.setdefault(k, []).append(w)
        for k, ws in sorted(terms.items()):
            delta_f = ca.mtimes(ca.DM(a_map), sum(ws[1:], ws[0]))  # (4,) N
            opti.subject_to(opti.bounded(-frac * ca.DM(down), delta_f, frac * ca.DM(up)))
            if target.moving or any(agents[ns].moving for ns in names):
                norm_sq = ca.sumsqr(delta_f / ca.DM(np.minimum(up, down)))
                cost += problem.weights.exposure * h * norm_sq

    opti.minimize(cost)
    opti.solver(
        "ipopt",
        {"expand": True, "print_time": False},
        {
            "print_level": 0,
            "sb": "yes",
            "max_iter": problem.max_iterations,
            "max_cpu_time": problem.max_cpu_time_s,
            "tol": 1e-6,
            "acceptable_tol": 1e-4,
            "mu_strategy": "adaptive",
        },
    )
    build_time = time.perf_counter() - t_build
    if progress is not None:
        progress(f"optimiser: {opti.nx} variables, {opti.ng} constraints, built in {build_time:.2f} s")
    t0 = time.perf_counter()
    try:
        sol = opti.solve()
        value, stats, ok = sol.value, sol.stats(), True
    except RuntimeError:
        value, stats, ok = opti.debug.value, opti.stats(), False
    solve_time = time.perf_counter() - t0
    status = str(stats.get("return_status", "unknown"))
    ok = ok and bool(stats.get("success", False))
    out_p, out_v, out_a, out_j = {}, {}, {}, {}
    for a in problem.agents:
        if a.moving:
            out_p[a.name] = np.asarray(value(pos[a.name])).T.reshape(n + 1, 3)
            out_v[a.name] = np.asarray(value(vel[a.name])).T.reshape(n + 1, 3)
            out_a[a.name] = np.asarray(value(acc[a.name])).T.reshape(n + 1, 3)
            out_j[a.name] = np.asarray(value(jerk[a.name])).T.reshape(n, 3)
        else:
            out_p[a.name] = np.tile(np.asarray(a.start_m, float), (n + 1, 1))
            out_v[a.name] = np.zeros((n + 1, 3))
            out_a[a.name] = np.zeros((n + 1, 3))
            out_j[a.name] = np.zeros((n, 3))
    return OcpSolution(
        success=ok,
        status=status,
        duration_s=float(value(T)),
        position_m=out_p,
        velocity_mps=out_v,
        acceleration_mps2=out_a,
        jerk_mps3=out_j,
        iterations=int(stats.get("iter_count", 0)),
        solve_time_s=solve_time,
        build_time_s=build_time,
        objective=float(value(cost)),
    )


def _warm(values: np.ndarray | None, default: np.ndarray, n: int) -> np.ndarray:
    if values is None:
        return np.tile(np.asarray(default, float), (n + 1, 1))
    arr = np.asarray(values, float)
    if arr.shape != (n + 1, 3):
        raise ValueError(f"warm start must have shape ({n + 1}, 3), got {arr.shape}")
    return arr


def sample_solution(solution: OcpSolution, times_s: np.ndarray, *, time_scale: float = 1.0) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Evaluate the piecewise-constant-jerk trajectories exactly at ``times_s`` (M,), s.

    ``time_scale`` >= 1 slows the whole solution uniformly (duration x scale; v / s, a / s^2).
    Returns {name: (position_m (M, 3), velocity_mps (M, 3), acceleration_mps2 (M, 3))}.
    """
    n = next(iter(solution.jerk_mps3.values())).shape[0]
    h = solution.duration_s / n
    tau = np.clip(np.asarray(times_s, float) / time_scale, 0.0, solution.duration_s)
    k = np.minimum((tau / h).astype(int), n - 1)
    dt = (tau - k * h)[:, None]
    out = {}
    for name in solution.position_m:
        p0, v0 = solution.position_m[name][k], solution.velocity_mps[name][k]
        a0, j = solution.acceleration_mps2[name][k], solution.jerk_mps3[name][k]
        p = p0 + v0 * dt + a0 * dt**2 / 2 + j * dt**3 / 6
        v = (v0 + a0 * dt + j * dt**2 / 2) / time_scale
        a = (a0 + j * dt) / time_scale**2
        out[name] = (p, v, a)
    return out
