"""Decomposed optimisation for swarms: one vehicle at a time against the others' fixed trajectories.

The joint problem of :mod:`proxplan.planner.optimizer.ocp` grows with the square of the number of vehicles (every
pair's separation, invalid-zone and authority terms at every check point); on this machine it stops
converging from about 8 formation vehicles on. Here each vehicle is re-optimised in turn
(prioritised re-optimisation, Gauss-Seidel rounds): a small :class:`proxplan.planner.optimizer.ocp_problem.OcpProblem`
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
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from proxplan.planfile import Plan, VehicleTrajectory
from proxplan.planner.optimizer.ocp import build_and_solve, sample_solution
from proxplan.planner.optimizer.ocp_problem import OcpAgent, OcpProblem, OcpSolution, OcpWeights, scenario_fields
from proxplan.planner.optimizer.swarm_field import CHECK_DT_S, SwarmField, kinematic_conflict, static_conflict
from proxplan.planner.optimizer.warm_problem import task_agent
from proxplan.planner.timing.durations import min_segment_duration_s
from proxplan.planner.timing.plan_grid import vehicle_arrival_s as arrival_s


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

    def problem(
        self,
        names: str | Sequence[str],
        T: float,
        warm: Mapping[str, tuple[np.ndarray, np.ndarray, np.ndarray]] | None,
    ) -> OcpProblem:
        """The problem of the vehicles ``names`` (one, or the group of a joint move,
        :mod:`proxplan.planner.optimizer.joint_move`) moving together over the fixed duration ``T``
        (s), every other vehicle within ``reach_m`` of their warm paths a fixed trajectory with the
        disturbance from outside the problem as its background. ``warm[name]``: (p, v, a) on the
        n+1 nodes; a mover without one is warm-started on its current path re-timed to T."""
        sc, opt = self.sc, self.opt
        movers = [names] if isinstance(names, str) else list(names)
        n = int(np.clip(math.ceil(T / opt.interval_s), opt.min_intervals, opt.max_intervals))
        nodes = np.linspace(0.0, T, n + 1)
        tq = np.concatenate([nodes, 0.5 * (nodes[:-1] + nodes[1:])])
        agents, wqs = [], []
        for name in movers:  # movers have goals and no docks (reoptimize_plan, joint_moves): no dock fields
            w = (warm or {}).get(name) or retimed_path(self.traj[name], nodes)
            wqs.append(np.vstack([w[0], 0.5 * (w[0][:-1] + w[0][1:])]))
            agents.append(task_agent(sc, name, w, moving=True))
        wrench, extents = {}, {}

        def pair(a: str, b: str) -> None:
            wrench[(a, b)], wrench[(b, a)] = self.fn(a, b), self.fn(b, a)
            if self.extent_provider is not None:  # the table is zero beyond its extent: sparse terms
                extents[(a, b)], extents[(b, a)] = self.extent(a, b), self.extent(b, a)

        for i, a in enumerate(movers):
            for b in movers[i + 1 :]:
                pair(a, b)
        for o in self.field.names:
            if o in movers:
                continue
            path = self.field.at(o, tq)
            near = [m for m, wq in zip(movers, wqs) if np.hypot(*(path - wq)[:, :2].T).min() <= opt.reach_m]
            if not near:
                continue  # sparse pairs: never within reach along the warm starts
            other = sc.vehicles[o]
            agents.append(
                OcpAgent(
                    name=o,
                    vehicle=other.vehicle,
                    moving=False,
                    start_m=path[0],
                    body_radius_m=float(other.body_radius_m),
                    fixed_path_m=path,
                    background_wrench=self.field.wrench_at(o, tq, without=movers),
                )
            )
            for m in near:
                pair(o, m)
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

    def slowed(self, names: Sequence[str], sol: OcpSolution) -> tuple[float, dict, str]:
        """The least uniform slow-down (time scale, up to ``max_slowdown``) of the solution at which
        every vehicle of ``names`` keeps its kinematic limits on the plan grid (one factor for all:
        their relative timing is kept), their (p, v, a) there, and why not ("" when found)."""
        scale, why = 1.0, ""
        while scale <= self.opt.max_slowdown + 1e-9:
            sampled = sample_solution(sol, self.grid, time_scale=scale)
            why = ""
            for name in names:
                why = why or kinematic_conflict(self.sc.vehicles[name], *sampled[name][1:], float(self.plan.dt_s)) or ""
            if not why:
                return scale, sampled, ""
            scale *= 1.05
        return scale, {}, why

    def candidate(self, name: str, sol: OcpSolution) -> tuple[VehicleTrajectory | None, np.ndarray | None, str]:
        """The solution on the plan grid (uniformly slowed if a limit breaks between nodes) and on
        the check grid, or None and why not."""
        task = self.sc.vehicles[name]
        scale, sampled, why = self.slowed([name], sol)
        if why:
            return None, None, why
        p, v, a = sampled[name]
        pf = sample_solution(sol, self.field.t_s, time_scale=scale)[name][0]
        why = static_conflict(self.sc, name, pf) or ""
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
            pb = self.problem(name, T, None if warm is None else {name: warm})
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
    vehicles: list[str] | None = None,
) -> ReoptResult:
    """Re-optimise the moving vehicles of ``plan`` (only ``vehicles`` when given, e.g. those that set
    a swarm's makespan; the others stay fixed as moving obstacles) one at a time (latest arrival
    first) in rounds until no vehicle improves, ``max_rounds`` or the time budget; returns the best
    plan that passed ``proxplan.verify.verify_plan`` (the input plan when none did better). Scenarios
    with docks are not decomposed (the dock pair must be optimised together)."""
    from proxplan.verify import verify_plan

    t0 = time.perf_counter()
    deadline = t0 + options.time_budget_s
    ro = _Reoptimizer(scenario, plan, options, wrench_provider, extent_provider, progress)
    movers = [n for n, t in scenario.vehicles.items() if not t.hover and t.goal_m is not None and t.dock_with is None]
    if vehicles is not None:
        movers = [n for n in movers if n in set(vehicles)]
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
