"""Decomposed optimisation for swarms: one vehicle at a time against the others' fixed trajectories.

The joint problem of :mod:`proxplan.planner.ocp` grows with the square of the number of vehicles (every
pair's separation, invalid-zone and authority terms at every check point); on this machine it stops
converging from about 8 formation vehicles on. Here each vehicle is re-optimised in turn
(prioritised re-optimisation, Gauss-Seidel rounds): a small :class:`proxplan.planner.ocp_problem.OcpProblem`
with that one vehicle moving over a fixed duration T (s) and only the vehicles that come within
``reach_m`` of its warm path as fixed trajectories (sparse pairs), the disturbance the fixed vehicles
already receive from everyone else as a constant background (``OcpAgent.background_wrench``).

Per vehicle: T is tried from near its own minimum time (``timing.min_segment_duration_s``, the
time its goal is free of the others) up towards its current arrival; the warm start is its current
path compressed in time. A candidate is accepted only when a direct model check on a 0.02 s grid
(:class:`SwarmField`: separation, invalid zone, authority of the vehicle *and* of every vehicle in
its jet, summed over all sources with ``proxplan.costmaps.pair_wrench``, as the verifier; workspace, obstacles,
kinematic limits) passes; a solution that moved into pairs outside the problem is re-solved once
with the pairs re-selected around it. After every round the whole plan goes through the independent
verifier (``proxplan.verify.verify_plan``); only verified plans are kept, so a time budget always returns
the best verified plan found so far. World frame, z up; m, s, N, N m.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from proxplan.costmaps import pair_wrench
from proxplan.physics import ModelOptions, authority_usage, invalid_zone_mask
from proxplan.planfile import Plan, VehicleTrajectory
from proxplan.planner.ocp import build_and_solve, sample_solution
from proxplan.planner.ocp_problem import OcpAgent, OcpProblem, OcpSolution, OcpWeights, scenario_fields
from proxplan.planner.timing import min_segment_duration_s
from proxplan.verify import REST_SPEED_MPS, tube_offsets

CHECK_DT_S = 0.02  # grid of the per-vehicle model check, s (the verifier re-checks at 0.01 s)
REST_MPS = 1e-4  # speed below which a vehicle counts as arrived, m/s


@dataclass(frozen=True)
class ReoptOptions:
    """Tuning of the decomposed optimisation."""

    time_budget_s: float = 60.0  # wall-clock budget of all rounds, s
    interval_s: float = 0.2  # target grid step of each vehicle's problem, s
    min_intervals: int = 12
    max_intervals: int = 24
    reach_m: float = 2.5  # others within this horizontal distance of the warm path enter the problem, m
    max_rounds: int = 8
    pair_radius_m: float = 1.0  # separation / invalid-zone terms only within this much of contact, m
    extent_margin_m: float = 0.3  # authority terms only within the wrench table's extent + this, m
    max_cpu_time_s: float = 10.0  # IPOPT limit of one vehicle's solve, s
    max_iterations: int = 80  # a solve that converges needs ~20-40; an infeasible T is dropped early
    max_linearizations: int = 2
    first_step: float = 0.4  # first T tried: this far from the lower bound towards the current arrival
    lower_bound_factor: float = 1.1  # first duration tried: this x the vehicle's minimum time
    max_slowdown: float = 1.2  # uniform slow-down allowed to repair a kinematic breach between nodes
    # check-point authority bound, fraction of authority_fraction. The joint problem keeps 0.9; here
    # every candidate is checked with the model on a 0.02 s grid (SwarmField) and every round by the
    # verifier, and the fixed vehicles often already use 90-100 % of the limit where the sampling
    # plan passes them (its cut-off is at the full level): with 0.9 the problem of a vehicle whose
    # jet passes over them is infeasible even at its current timing (32-vehicle formation)
    authority_margin: float = 0.98
    weights: OcpWeights = OcpWeights()


@dataclass(frozen=True)
class ReoptResult:
    """Outcome of :func:`reoptimize_plan`: ``plan`` is verified (or the input plan unchanged)."""

    plan: Plan
    improved: bool
    message: str
    solves: int
    iterations: int
    rounds: int
    solve_time_s: float  # IPOPT wall time summed over vehicles, s
    last_status: str = "none"  # IPOPT return status of the last solve
    max_violation: float = float("nan")  # largest final constraint violation over the converged solves


def arrival_s(tr: VehicleTrajectory) -> float:
    """Time after which the trajectory no longer moves, s (0 for a vehicle that never moves)."""
    moving = np.flatnonzero(np.linalg.norm(tr.velocity_mps, axis=1) > REST_MPS)
    if moving.size == 0:
        return 0.0
    return float(tr.t_s[min(moving[-1] + 1, tr.t_s.size - 1)])


class SwarmField:
    """Every vehicle's position on a check grid and the total disturbance wrench on each (sum over
    all sources above it, ``proxplan.costmaps.pair_wrench``: S0-3..S0-8 plus the scenario's effects, as the
    verifier), updated as vehicles change; the non-zero pair contributions are kept."""

    def __init__(self, scenario, plan: Plan, *, dt_s: float = CHECK_DT_S):
        self.scenario = scenario
        self.options = ModelOptions(field_form=scenario.field_form) if scenario.field_form else ModelOptions()
        self.effects = tuple(getattr(scenario, "effects", ()))  # a calibrated model's, as the verifier
        self.t_s = np.arange(0.0, float(plan.t_s[-1]) + dt_s / 2, dt_s)
        self.pos = {n: tr.position_at(self.t_s) for n, tr in plan.vehicles.items()}
        self.vehicle = {n: scenario.vehicles[n].vehicle for n in plan.vehicles}
        self.names = list(plan.vehicles)
        m = self.t_s.size
        self.force = {n: np.zeros((m, 3)) for n in self.names}
        self.torque = {n: np.zeros((m, 3)) for n in self.names}
        # (source, target) -> its (force, torque) at the current positions; absent: zero
        self._pairs: dict[tuple[str, str], tuple[np.ndarray, np.ndarray]] = {}
        # contributions of the last candidate checked: (name, id(p_new), {key: (force, torque)})
        self._candidate: tuple[str, int, dict] | None = None
        for t in self.names:
            for s in self.names:
                if s != t:
                    self._store(s, t, self.contribution(s, t, self.pos[s], self.pos[t]))
                    f, q = self.current(s, t)
                    self.force[t] += f
                    self.torque[t] += q

    def _store(self, source: str, target: str, fq: tuple[np.ndarray, np.ndarray]) -> None:
        if np.any(fq[0]) or np.any(fq[1]):
            self._pairs[(source, target)] = fq
        else:
            self._pairs.pop((source, target), None)

    def current(self, source: str, target: str) -> tuple[np.ndarray, np.ndarray]:
        """(force_N, torque_Nm) (M, 3) of ``source`` on ``target`` at the current positions."""
        zero = np.zeros((self.t_s.size, 3))
        return self._pairs.get((source, target), (zero, zero))

    def contribution(self, source: str, target: str, p_source: np.ndarray, p_target: np.ndarray):
        """(force_N (M, 3), torque_Nm (M, 3)) of ``source`` on ``target`` at the given positions."""
        off = p_target - p_source
        f, q = np.zeros_like(off), np.zeros_like(off)
        below = -off[:, 2] > 1e-6
        if not self.effects:  # base model: a jet 6 m to the side is below 1e-6 of any authority
            below &= np.hypot(off[:, 0], off[:, 1]) < 6.0
        if below.any():
            f[below], q[below] = pair_wrench(
                self.vehicle[source], self.vehicle[target], off[below], self.options, self.effects
            )
        return f, q

    def tube_contribution(self, source: str, target: str, p_source: np.ndarray, p_target: np.ndarray, use):
        """As :meth:`contribution`, but where ``use`` (M,) holds with the target at the worst point of
        the tracking tube (``proxplan.verify.tube_offsets``, the verifier's authority-tube rule)."""
        f, q = self.contribution(source, target, p_source, p_target)
        tube = self.scenario.limits.tracking_margin_m
        off = p_target - p_source
        use = use & (-off[:, 2] > 1e-6)
        if tube <= 0.0 or not use.any():
            return f, q
        veh = self.vehicle[target]
        best_u = np.full(int(use.sum()), -np.inf)
        for o in tube_offsets(off[use], tube):
            fo, qo = pair_wrench(self.vehicle[source], veh, o, self.options, self.effects)
            u = authority_usage(veh, fo, qo)
            better = u > best_u
            best_u[better] = u[better]
            rows = np.flatnonzero(use)[better]
            f[rows], q[rows] = fo[better], qo[better]
        return f, q

    def usage(self, name: str) -> np.ndarray:
        return authority_usage(self.vehicle[name], self.force[name], self.torque[name])

    def conflicts(self, name: str, p_new: np.ndarray) -> tuple[np.ndarray, str | None]:
        """(mask (M,) of check times where ``name`` flying ``p_new`` (M, 3) breaks a pair rule, the
        first broken rule as text). Authority of another vehicle counts only where the change makes
        it worse than before and over the limit."""
        lim = self.scenario.limits
        frac = lim.authority_fraction
        me = self.vehicle[name]
        bad = np.zeros(self.t_s.size, dtype=bool)
        first: list[tuple[int, str]] = []

        def note(mask: np.ndarray, what: str) -> None:
            nonlocal bad
            if mask.any():
                bad |= mask
                first.append((int(np.argmax(mask)), what))

        force, torque = np.zeros_like(p_new), np.zeros_like(p_new)
        tube_force, tube_torque = np.zeros_like(p_new), np.zeros_like(p_new)  # the verifier's authority-tube rule
        new_pairs: dict[tuple[str, str], tuple[np.ndarray, np.ndarray]] = {}
        me_moving = self._moving(p_new)
        for o in self.names:
            if o == name:
                continue
            other = self.vehicle[o]
            off = p_new - self.pos[o]
            # the tracking tube while either vehicle of the pair moves, as the verifier checks
            tube = np.where(me_moving | self._moving(self.pos[o]), lim.tracking_margin_m, 0.0)  # (M,) m
            sep = max(lim.min_separation_m, me.body_radius_m + other.body_radius_m) + tube
            note(np.linalg.norm(off, axis=1) < sep, f"separation from {o}")
            if lim.invalid_zone_rule != "model":
                note(invalid_zone_mask(other, me, off, tube), f"invalid zone of {o}")
                note(invalid_zone_mask(me, other, -off, tube), f"invalid zone on {o}")
            f, q = new_pairs[(o, name)] = self.contribution(o, name, self.pos[o], p_new)
            force += f
            torque += q
            pair_moving = tube > 0.0
            ft, qt = self.tube_contribution(o, name, self.pos[o], p_new, pair_moving)
            tube_force += ft
            tube_torque += qt
            f_old, q_old = self.current(name, o)
            f_new, q_new = new_pairs[(name, o)] = self.contribution(name, o, p_new, self.pos[o])
            if np.any(f_new) or np.any(f_old):
                before = authority_usage(other, self.force[o], self.torque[o])
                after = authority_usage(other, self.force[o] - f_old + f_new, self.torque[o] - q_old + q_new)
                note((after > frac) & (after > before + 1e-9), f"authority of {o} in its jet")
                f_tb, q_tb = self.tube_contribution(name, o, p_new, self.pos[o], pair_moving)
                after_t = authority_usage(other, self.force[o] - f_old + f_tb, self.torque[o] - q_old + q_tb)
                note((after_t > frac) & (after_t > before + 1e-9), f"authority of {o} within the tube")
        note(authority_usage(me, force, torque) > frac, "authority")
        note(authority_usage(me, tube_force, tube_torque) > frac, "authority within the tube")
        self._candidate = (name, id(p_new), new_pairs)
        return bad, (min(first)[1] if first else None)

    def _moving(self, p: np.ndarray) -> np.ndarray:
        """(M,) bool: the vehicle at positions ``p`` (M, 3) on the check grid moves at least at the
        verifier's rest speed (proxplan.verify.REST_SPEED_MPS, m/s)."""
        speed = np.linalg.norm(np.gradient(p, self.t_s, axis=0), axis=1) if p.shape[0] > 1 else np.zeros(1)
        return speed >= REST_SPEED_MPS

    def replace(self, name: str, p_new: np.ndarray) -> None:
        """Move ``name`` onto ``p_new`` (M, 3) and update every affected wrench total."""
        known = self._candidate[2] if self._candidate and self._candidate[:2] == (name, id(p_new)) else {}
        force, torque = np.zeros_like(p_new), np.zeros_like(p_new)
        for o in self.names:
            if o == name:
                continue
            f, q = known.get((o, name)) or self.contribution(o, name, self.pos[o], p_new)
            force += f
            torque += q
            f_old, q_old = self.current(name, o)
            f_new, q_new = known.get((name, o)) or self.contribution(name, o, p_new, self.pos[o])
            self.force[o] += f_new - f_old
            self.torque[o] += q_new - q_old
            self._store(o, name, (f, q))
            self._store(name, o, (f_new, q_new))
        self.force[name], self.torque[name] = force, torque
        self.pos[name] = p_new
        self._candidate = None

    def at(self, name: str, t_s: np.ndarray) -> np.ndarray:
        """Positions (K, 3) of ``name`` at ``t_s`` (K,) by linear interpolation of the check grid."""
        p = self.pos[name]
        return np.column_stack([np.interp(t_s, self.t_s, p[:, i]) for i in range(3)])

    def wrench_at(self, name: str, t_s: np.ndarray, *, without: str) -> np.ndarray:
        """Rows (F_z N, tau_x N m, tau_y N m) (3, K) on ``name`` at ``t_s`` from every source but
        ``without`` (the vehicle being optimised)."""
        f_w, q_w = self.current(without, name)
        f, q = self.force[name] - f_w, self.torque[name] - q_w
        cols = (f[:, 2], q[:, 0], q[:, 1])
        return np.vstack([np.interp(t_s, self.t_s, c) for c in cols])


def _static_conflict(scenario, name: str, p: np.ndarray) -> str | None:
    """Workspace and obstacle breaches of the body disc at positions ``p`` (K, 3)."""
    task, lim = scenario.vehicles[name], scenario.limits
    rb, mz = task.vehicle.body_radius_m, lim.obstacle_margin_m
    lo = np.asarray(scenario.workspace_min_m) + np.array([rb, rb, mz])
    hi = np.asarray(scenario.workspace_max_m) - np.array([rb, rb, mz])
    if np.any(p < lo - 1e-9) or np.any(p > hi + 1e-9):
        return "workspace"
    for i, box in enumerate(scenario.obstacles):
        grow = np.array([rb + mz, rb + mz, mz])
        inside = np.all((p > box.min_m - grow) & (p < box.max_m + grow), axis=1)
        if inside.any():
            return f"obstacle[{i}]"
    return None


def _kinematic_conflict(task, v: np.ndarray, a: np.ndarray, dt_s: float) -> str | None:
    if np.linalg.norm(v, axis=1).max() > task.max_speed_mps * 1.0:
        return "speed"
    if np.linalg.norm(a, axis=1).max() > task.max_accel_mps2 * 1.0:
        return "acceleration"
    if a.shape[0] > 1 and (np.linalg.norm(np.diff(a, axis=0), axis=1) / dt_s).max() > task.max_jerk_mps3 * 1.05:
        return "jerk"
    return None


def retimed_path(tr: VehicleTrajectory, nodes_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The path of ``tr`` flown over ``nodes_s`` (n+1,) instead (warm start of a shorter duration):
    arc length follows the minimum-jerk law s(tau) = L (10 tau^3 - 15 tau^4 + 6 tau^5), velocity
    and acceleration by differences on the nodes. Compressing the old timing instead would scale
    speed, acceleration and jerk by k, k^2, k^3 and start IPOPT far outside the limits."""
    end = max(arrival_s(tr), float(tr.t_s[1]) if tr.t_s.size > 1 else 0.0)
    dense = tr.position_at(np.linspace(0.0, end, 400))
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(dense, axis=0), axis=1))])
    tau = (nodes_s - nodes_s[0]) / max(nodes_s[-1] - nodes_s[0], 1e-9)
    s = arc[-1] * (10 * tau**3 - 15 * tau**4 + 6 * tau**5)
    p = np.column_stack([np.interp(s, arc, dense[:, i]) for i in range(3)])
    h = float(nodes_s[1] - nodes_s[0])
    v = np.gradient(p, h, axis=0)
    a = np.gradient(v, h, axis=0)
    v[[0, -1]] = 0.0
    a[[0, -1]] = 0.0
    return p, v, a


class _Reoptimizer:
    def __init__(
        self, scenario, plan: Plan, options: ReoptOptions, wrench_provider: Callable, extent_provider, progress
    ):
        self.sc, self.plan, self.opt = scenario, plan, options
        self.provider = wrench_provider
        self.extent_provider = extent_provider
        self.extent_cache: dict[tuple[int, int], object] = {}
        self.progress = progress
        self.field = SwarmField(scenario, plan)
        self.grid = plan.t_s.copy()
        self.traj = dict(plan.vehicles)
        self.cache: dict[tuple[int, int], object] = {}
        self.solves = self.iterations = 0
        self.solve_time = 0.0
        self.last_status = "none"
        self.max_violation = 0.0

    def _per_type_pair(self, what: str, source: str, target: str):
        """The wrench function (``what`` = "fn") or table extent ("extent") of a pair, built once
        per pair of vehicle types."""
        s, t = self.sc.vehicles[source].vehicle, self.sc.vehicles[target].vehicle
        cache, provider = (self.cache, self.provider) if what == "fn" else (self.extent_cache, self.extent_provider)
        key = (id(s), id(t))
        if key not in cache:
            cache[key] = provider(s, t, self.sc)
        return cache[key]

    def fn(self, source: str, target: str):
        return self._per_type_pair("fn", source, target)

    def extent(self, source: str, target: str):
        return self._per_type_pair("extent", source, target)

    def goal_free_s(self, name: str) -> float:
        """Earliest time from which ``name`` resting at its goal breaks no pair rule, s."""
        goal = np.asarray(self.sc.vehicles[name].goal_m, float)
        bad, _ = self.field.conflicts(name, np.tile(goal, (self.field.t_s.size, 1)))
        idx = np.flatnonzero(bad)
        return 0.0 if idx.size == 0 else float(self.field.t_s[idx[-1]] + CHECK_DT_S)

    def problem(self, name: str, T: float, warm: tuple[np.ndarray, np.ndarray, np.ndarray] | None) -> OcpProblem:
        sc, opt = self.sc, self.opt
        task = sc.vehicles[name]
        n = int(np.clip(math.ceil(T / opt.interval_s), opt.min_intervals, opt.max_intervals))
        nodes = np.linspace(0.0, T, n + 1)
        tq = np.concatenate([nodes, 0.5 * (nodes[:-1] + nodes[1:])])
        if warm is None:
            warm = retimed_path(self.traj[name], nodes)
        wq = np.vstack([warm[0], 0.5 * (warm[0][:-1] + warm[0][1:])])
        agents = [
            OcpAgent(
                name=name,
                vehicle=task.vehicle,
                moving=True,
                start_m=np.asarray(task.start_m, float),
                goal_m=np.asarray(task.goal_m, float),
                max_speed_mps=task.max_speed_mps,
                max_accel_mps2=task.max_accel_mps2,
                max_jerk_mps3=task.max_jerk_mps3,
                body_radius_m=float(task.body_radius_m),
                warm_position_m=warm[0],
                warm_velocity_mps=warm[1],
                warm_acceleration_mps2=warm[2],
            )
        ]
        wrench, extents = {}, {}
        for o in self.field.names:
            if o == name:
                continue
            path = self.field.at(o, tq)
            if np.hypot(*(path - wq)[:, :2].T).min() > opt.reach_m:
                continue  # sparse pairs: never within reach along the warm start
            other = sc.vehicles[o]
            agents.append(
                OcpAgent(
                    name=o,
                    vehicle=other.vehicle,
                    moving=False,
                    start_m=path[0],
                    body_radius_m=float(other.body_radius_m),
                    fixed_path_m=path,
                    background_wrench=self.field.wrench_at(o, tq, without=name),
                )
            )
            wrench[(o, name)] = self.fn(o, name)
            wrench[(name, o)] = self.fn(name, o)
            if self.extent_provider is not None:  # the table is zero beyond its extent: sparse terms
                extents[(o, name)] = self.extent(o, name)
                extents[(name, o)] = self.extent(name, o)
        return OcpProblem(
            agents=tuple(agents),
            n_intervals=n,
            warm_duration_s=T,
            max_duration_s=T,
            fixed_duration_s=T,
            **scenario_fields(sc),
            wrench_functions=wrench,
            interaction_extent=extents,
            interaction_radius_m=opt.pair_radius_m,
            extent_margin_m=opt.extent_margin_m,
            weights=opt.weights,
            max_cpu_time_s=opt.max_cpu_time_s,
            max_iterations=opt.max_iterations,
            max_linearizations=opt.max_linearizations,
            authority_margin=opt.authority_margin,
        )

    def candidate(self, name: str, sol: OcpSolution) -> tuple[VehicleTrajectory | None, np.ndarray | None, str]:
        """The solution on the plan grid (uniformly slowed if a limit breaks between nodes) and on
        the check grid, or None and why not."""
        task = self.sc.vehicles[name]
        scale, why = 1.0, ""
        while scale <= self.opt.max_slowdown + 1e-9:
            p, v, a = sample_solution(sol, self.grid, time_scale=scale)[name]
            why = _kinematic_conflict(task, v, a, float(self.plan.dt_s)) or ""
            if not why:
                break
            scale *= 1.05
        if why:
            return None, None, why
        pf = sample_solution(sol, self.field.t_s, time_scale=scale)[name][0]
        why = _static_conflict(self.sc, name, pf) or ""
        if not why:
            bad, what = self.field.conflicts(name, pf)
            why = what or ""
        if why:
            return None, pf, why
        return VehicleTrajectory(name, task.type_name, task.vehicle, self.grid.copy(), p, v, a), pf, ""

    def attempt(self, name: str, T: float, deadline: float) -> tuple[bool, str]:
        """One duration T (s): solve, check; with a second pass (pairs re-selected around the first
        solution) when the solution moved into pairs the problem did not have."""
        T_cur = arrival_s(self.traj[name])
        warm = None
        why = "time budget reached"
        for _ in range(2):
            if time.perf_counter() > deadline:
                break
            pb = self.problem(name, T, warm)
            left = max(0.5, deadline - time.perf_counter())
            pb = replace(pb, max_cpu_time_s=min(pb.max_cpu_time_s, left), max_wall_time_s=left)
            sol = build_and_solve(pb)
            self.solves += 1
            self.iterations += sol.iterations
            self.solve_time += sol.solve_time_s
            self.last_status = sol.status
            if sol.success:
                self.max_violation = max(self.max_violation, sol.constraint_violation)
            if not sol.success:
                return False, f"IPOPT {sol.status} at T = {T:.2f} s"
            tr, pf, why = self.candidate(name, sol)
            if tr is not None and pf is not None:
                if arrival_s(tr) >= T_cur - self.plan.dt_s / 2:
                    return False, "not faster after the kinematic slow-down"
                self.field.replace(name, pf)
                self.traj[name] = tr
                return True, f"{T_cur:.2f} s -> {arrival_s(tr):.2f} s"
            warm = (sol.position_m[name], sol.velocity_mps[name], sol.acceleration_mps2[name])
        return False, why

    def improve(self, name: str, deadline: float) -> tuple[bool, str]:
        """Try to make ``name`` arrive earlier: first at ``first_step`` of the way from a lower bound
        (1.1 x the minimum time over its current path length; the time its goal is free) to its
        current arrival, after a failure at 0.8 of the way. On success the field and the trajectory
        are updated (later rounds step again from the new arrival)."""
        task = self.sc.vehicles[name]
        tr = self.traj[name]
        T_cur = arrival_s(tr)
        length = float(np.linalg.norm(np.diff(tr.position_m, axis=0), axis=1).sum())
        T_lb = min_segment_duration_s(length, task.kinematic_limits)
        lo = max(self.opt.lower_bound_factor * T_lb, self.goal_free_s(name) + 0.1)
        if lo > T_cur - 2 * self.plan.dt_s:
            return False, "already near its minimum time"
        ok, why = self.attempt(name, lo + self.opt.first_step * (T_cur - lo), deadline)
        if ok:  # closer to the bound in the next round: the budget goes to the other vehicles first
            return ok, why
        return self.attempt(name, lo + 0.8 * (T_cur - lo), deadline)

    def plan_now(self) -> Plan:
        end = max([arrival_s(tr) for tr in self.traj.values()] + [self.plan.dt_s])
        k = min(self.grid.size, int(round(end / self.plan.dt_s)) + 2)
        vehicles = {
            n: VehicleTrajectory(
                n,
                tr.type_name,
                tr.vehicle,
                tr.t_s[:k],
                tr.position_m[:k],
                tr.velocity_mps[:k],
                tr.acceleration_mps2[:k],
            )
            for n, tr in self.traj.items()
        }
        return replace(self.plan, vehicles=vehicles, metrics=dict(self.plan.metrics), notes=list(self.plan.notes))


def makespan_of(plan: Plan) -> float:
    return max([arrival_s(tr) for tr in plan.vehicles.values()] + [0.0])


def reoptimize_plan(
    scenario,
    plan: Plan,
    *,
    wrench_provider: Callable,
    extent_provider: Callable | None = None,
    options: ReoptOptions = ReoptOptions(),
    progress: Callable | None = None,
) -> ReoptResult:
    """Re-optimise the moving vehicles of ``plan`` one at a time (latest arrival first) in rounds
    until no vehicle improves, ``max_rounds`` or the time budget; returns the best plan that passed
    ``proxplan.verify.verify_plan`` (the input plan when none did better). Scenarios with docks are not
    decomposed (the dock pair must be optimised together)."""
    from proxplan.verify import verify_plan

    t0 = time.perf_counter()
    deadline = t0 + options.time_budget_s
    ro = _Reoptimizer(scenario, plan, options, wrench_provider, extent_provider, progress)
    movers = [n for n, t in scenario.vehicles.items() if not t.hover and t.goal_m is not None and t.dock_with is None]
    best, best_makespan = plan, makespan_of(plan)
    start_makespan = best_makespan
    rounds, log, stale = 0, [], 0
    for rnd in range(options.max_rounds):
        if time.perf_counter() > deadline:
            log.append("time budget reached")
            break
        rounds = rnd + 1
        saved = dict(ro.traj)
        current = makespan_of(ro.plan_now())
        order = sorted(movers, key=lambda n: -arrival_s(ro.traj[n]))
        if rnd > 0:  # later rounds: only the vehicles that set the makespan
            order = [n for n in order if arrival_s(ro.traj[n]) >= 0.9 * current]
        changed = []
        for i, name in enumerate(order):
            if time.perf_counter() > deadline:
                break
            if progress is not None:
                progress(f"optimiser round {rounds}: {name}", i / max(1, len(order)))
            ok, _ = ro.improve(name, deadline)
            if ok:
                changed.append(name)
        if not changed:
            break
        candidate = ro.plan_now()
        violations = verify_plan(candidate, scenario)
        if violations:
            # undo the changed vehicles the verifier names (else the whole round); stop if still failing
            named = {v.vehicle for v in violations} & set(changed)
            for n in named or changed:
                ro.traj[n] = saved[n]
                ro.field.replace(n, saved[n].position_at(ro.field.t_s))
            candidate = ro.plan_now()
            violations = verify_plan(candidate, scenario)
            log.append(f"round {rounds}: verifier rejected {sorted(named or changed)}; undone")
            if violations:
                for n in changed:
                    ro.traj[n] = saved[n]
                break
        ms = makespan_of(candidate)
        if not violations and ms < best_makespan - 1e-9:
            best, best_makespan = candidate, ms
        log.append(f"round {rounds}: {len(changed)} vehicle(s) faster, makespan {ms:.2f} s")
        stale = stale + 1 if ms >= current - 1e-9 else 0
        if stale >= 2:  # a round without a makespan gain can free the next vehicle; two rarely do
            break
    improved = best_makespan < start_makespan - 1e-9
    message = (
        f"decomposed optimisation ({len(movers)} vehicles one at a time against the others' fixed "
        f"trajectories, {rounds} round(s), {ro.solves} IPOPT solves, {time.perf_counter() - t0:.1f} s): "
        + (
            f"makespan {start_makespan:.2f} s -> {best_makespan:.2f} s, verified"
            if improved
            else "no verified improvement of the makespan"
        )
        + (f" [{'; '.join(log)}]" if log else "")
    )
    return ReoptResult(
        best, improved, message, ro.solves, ro.iterations, rounds, ro.solve_time, ro.last_status, ro.max_violation
    )
