"""The joint move of ``optimized`` for swarms (issue 37 item 6): the few vehicles that set a plan's
makespan, and the ones in their way, optimised together in one CasADi problem, every other vehicle
fixed as a moving obstacle.

One-at-a-time re-optimisation (:func:`proxplan.planner.optimizer.reoptimize.reoptimize_plan`) moves
one vehicle against all the others fixed; where the vehicles that set the makespan block each other
(or are blocked by vehicles that arrive earlier), none of them can arrive earlier alone. Here a
*move* is one problem (:meth:`proxplan.planner.optimizer.reoptimize._Reoptimizer.problem`: variables
and exact triple-integrator dynamics per mover, pairs among the movers and with the fixed vehicles
within reach, authority with the fixed vehicles' disturbance from outside the problem as their
background, solved with IPOPT) over a fixed duration T (s) shorter than the makespan:

- a *round* has a target T: ``fractions`` of the way from the latest vehicles' bound
  (``ReoptOptions.lower_bound_factor`` x their straight-line rest-to-rest time, and the time their
  goals are free) to the makespan, the shorter first. Every vehicle still arriving after T, latest
  first, is moved in one problem together with the vehicles whose current tracks come within
  ``way_radius_m`` (horizontally, at the same time) of its warm path, nearest first, up to
  ``max_movers`` in all; if that fails, alone. All movers then arrive by T (or, slowed to keep their
  limits, still before the makespan). A round that cannot bring every late vehicle in is undone;
  one that can is kept and the next round starts from the new makespan;
- warm starts: the late vehicle flies its current path re-timed to T
  (:func:`~proxplan.planner.optimizer.reoptimize.retimed_path`); a vehicle in the way that arrives
  by T already its current track.

A solution is accepted only when all movers, slowed by one common factor if a limit breaks between
nodes, pass the direct model check (:class:`~proxplan.planner.optimizer.swarm_field.SwarmField`, each
against the others at their new tracks) and the whole plan then passes the independent verifier
(``proxplan.verify.verify_plan``); anything else is undone. Budgets are counts (IPOPT problems,
iterations per problem), so the same plan and seed give the same result on any machine (IPOPT's CPU
limit stays as a safety net). World frame, z up; m, s.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from proxplan.planfile import Plan, VehicleTrajectory
from proxplan.planner.optimizer.ocp import build_and_solve, sample_solution
from proxplan.planner.optimizer.ocp_problem import OcpProblem
from proxplan.planner.optimizer.reoptimize import ReoptOptions, _Reoptimizer, makespan_of, retimed_path
from proxplan.planner.optimizer.swarm_field import static_conflict
from proxplan.planner.timing.durations import min_segment_duration_s
from proxplan.planner.timing.plan_grid import vehicle_arrival_s as arrival_s

# vehicles optimised together in one move: below the 8 formation vehicles from which the joint
# problem of all moving vehicles stops converging on this machine (reoptimize.py's docstring, issue 21)
JOINT_MAX_MOVERS = 3
# a vehicle is in a mover's way where its track comes within this horizontal distance of the mover's
# warm path at the same time, m: the pair radius of the decomposed problem (ReoptOptions.pair_radius_m),
# within which separation and invalid-zone terms enter it
WAY_RADIUS_M = ReoptOptions().pair_radius_m
# intervals of a joint move's problem at most (ReoptOptions.interval_s, 0.2 s, per interval below
# that): one vehicle crossing over another at full speed slipped through the jet between check
# points with 24 (h/2 = 0.17 s) and did not with 36 (0.11 s); watched on pillar-32 fixed (v006)
JOINT_MAX_INTERVALS = 36
# IPOPT's CPU limit per problem, s: a safety net only (the budget is its iteration count); high
# enough that no solve of the count budget meets it on a loaded machine, so the plan does not
# depend on the machine (its wall limit is twice this, OcpProblem.max_wall_time_s)
JOINT_SAFETY_CPU_S = 120.0
# durations tried per round: this far from the movers' bound towards the makespan (the decomposed
# optimiser tries 0.4 and 0.8 of the way for one vehicle; ReoptOptions.first_step)
JOINT_FRACTIONS = (0.4, 0.8)


@dataclass(frozen=True)
class JointOptions:
    """Count budgets of the joint moves."""

    max_movers: int = JOINT_MAX_MOVERS
    # IPOPT problems over all rounds; None: one per vehicle that may move (a round brings each late
    # vehicle in with one problem when it succeeds)
    max_solves: int | None = None
    max_rounds: int = 4
    fractions: tuple[float, ...] = JOINT_FRACTIONS
    way_radius_m: float = WAY_RADIUS_M
    max_iterations: int = 300  # IPOPT iterations per linearisation round of one problem
    # check-point authority bound, fraction of authority_fraction: the joint refinement's (OcpProblem's
    # default), as a joint move changes the relative timing of several vehicles at once
    authority_margin: float = OcpProblem.authority_margin
    # the problem's grid, pairs, margins
    reopt: ReoptOptions = field(
        default_factory=lambda: ReoptOptions(max_intervals=JOINT_MAX_INTERVALS, max_cpu_time_s=JOINT_SAFETY_CPU_S)
    )


@dataclass(frozen=True)
class JointResult:
    """Outcome of :func:`joint_moves`: ``plan`` is verified (or the input plan unchanged)."""

    plan: Plan
    improved: bool
    message: str
    solves: int
    iterations: int
    log: tuple[str, ...] = ()


def _track_at(tr: VehicleTrajectory, nodes_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(p, v, a) of ``tr`` at ``nodes_s`` (n+1,), s (linear interpolation of its samples)."""

    def at(x: np.ndarray) -> np.ndarray:
        return np.column_stack([np.interp(nodes_s, tr.t_s, x[:, i]) for i in range(3)])

    return at(tr.position_m), at(tr.velocity_mps), at(tr.acceleration_mps2)


def straight_bound_s(scenario, name: str) -> float:
    """Rest-to-rest time of ``name`` on its straight line at its limits (no plan is faster), s."""
    task = scenario.vehicles[name]
    length = float(np.linalg.norm(np.subtract(task.goal_m, task.start_m)))
    return min_segment_duration_s(length, task.kinematic_limits)


class _Joint:
    def __init__(self, scenario, plan: Plan, options: JointOptions, wrench_provider, extent_provider):
        reopt = replace(options.reopt, max_iterations=options.max_iterations, authority_margin=options.authority_margin)
        self.ro = _Reoptimizer(scenario, plan, reopt, wrench_provider, extent_provider, None)
        self.sc, self.opt = scenario, options
        self.movable = [
            n for n, t in scenario.vehicles.items() if not t.hover and t.goal_m is not None and t.dock_with is None
        ]
        self.bound = {n: reopt.lower_bound_factor * straight_bound_s(scenario, n) for n in self.movable}
        self.solves = self.iterations = 0
        # IPOPT problems in all (count budget); None in the options: one per vehicle that may move
        self.max_solves = len(self.movable) if options.max_solves is None else options.max_solves

    def in_the_way(self, movers: list[str], T: float, room: int) -> list[str]:
        """Up to ``room`` vehicles whose tracks come within ``way_radius_m`` of a mover's warm path
        (re-timed to T) at the same time, nearest first."""
        ro = self.ro
        t = ro.field.t_s
        near: dict[str, float] = {}
        for m in movers:
            p = retimed_path(ro.traj[m], np.minimum(t, T))[0]
            for o in self.movable:
                if o in movers:
                    continue
                d = float(np.hypot(*(p - ro.field.pos[o])[:, :2].T).min())
                if d < self.opt.way_radius_m:
                    near[o] = min(d, near.get(o, np.inf))
        return sorted(near, key=lambda o: (near[o], o))[:room]

    def round_at(self, T: float, progress) -> tuple[bool, str, list[str]]:
        """Bring every vehicle arriving after T (s) in by T, latest first, each in one joint move
        with the vehicles in its way (moved vehicles then arrive at T, no later than the makespan
        target); (all done, what was moved or why not, the vehicles moved so far)."""
        ro = self.ro
        moved: list[str] = []
        done: list[str] = []
        tried: set[str] = set()
        limit_s = makespan_of(ro.plan_now())  # every vehicle must end before it
        while True:
            order = sorted(self.movable, key=lambda n: (-arrival_s(ro.traj[n]), n))
            late = [n for n in order if arrival_s(ro.traj[n]) > T + ro.plan.dt_s / 2]
            late = [n for n in late if n not in tried]
            if not late:
                return True, "; ".join(done), moved
            if self.solves >= self.max_solves:
                return False, f"count budget spent ({self.max_solves} problems) with {len(late)} late", moved
            first = late[0]
            way = self.in_the_way([first], T, self.opt.max_movers - 1)
            if progress is not None:
                progress(f"optimiser: joint move of {first} with {len(way)} in its way at T = {T:.2f} s")
            ok, why = self.move([first], way, T)
            if not ok and way and self.solves < self.max_solves:  # alone, as the one-at-a-time optimiser
                ok, alone = self.move([first], [], T)
                why, way = (alone, []) if ok else (f"{why}; alone: {alone}", way)
            if not ok:
                return False, f"{first} with {'+'.join(way) or 'none'}: {why}", moved
            moved += [first] + way
            for m in [first] + way:
                if arrival_s(ro.traj[m]) > limit_s - ro.plan.dt_s / 2:
                    return False, f"{m}: slowed past the makespan by the kinematic slow-down", moved
            tried.update([first] + way)  # in by T, or slowed past it but still before the makespan
            done.append(f"{first}+{len(way)}")

    def move(self, late: list[str], way: list[str], T: float) -> tuple[bool, str]:
        """Solve the movers' problem at T; place them in the field when every check passes."""
        ro = self.ro
        movers = late + way
        n = int(np.clip(np.ceil(T / ro.opt.interval_s), ro.opt.min_intervals, ro.opt.max_intervals))
        nodes = np.linspace(0.0, T, n + 1)
        # a vehicle in the way that already arrives by T keeps its track as warm start (else re-timed)
        warm = {o: _track_at(ro.traj[o], nodes) for o in way if arrival_s(ro.traj[o]) <= T}
        why = ""
        for _ in range(2):  # a second pass with the pairs re-selected around the first solution
            if self.solves >= self.max_solves:
                return False, why or "count budget spent"
            sol = build_and_solve(ro.problem(movers, T, warm))
            self.solves += 1
            self.iterations += sol.iterations
            if not sol.success:
                return False, f"IPOPT {sol.status} ({sol.iterations} iterations)"
            ok, why = self.place(movers, sol)
            if ok:
                return True, f"T {T:.2f} s, {sol.iterations} iterations{why}"
            warm = {m: (sol.position_m[m], sol.velocity_mps[m], sol.acceleration_mps2[m]) for m in movers}
        return False, why

    def place(self, movers: list[str], sol) -> tuple[bool, str]:
        """The movers of ``sol`` into the field and the plan when every check passes, else why not."""
        ro = self.ro
        scale, sampled, why = ro.slowed(movers, sol)
        if why:
            return False, f"kinematic limit ({why}) after the slow-down"
        fine = sample_solution(sol, ro.field.t_s, time_scale=scale)
        before = {m: ro.field.pos[m] for m in movers}
        for m in movers:
            ro.field.replace(m, fine[m][0])
        for m in movers:  # each against the others at their new tracks, from its own old one
            ro.field.replace(m, before[m])
            why = static_conflict(self.sc, m, fine[m][0]) or ro.field.conflicts(m, fine[m][0])[1] or ""
            ro.field.replace(m, fine[m][0])
            if why:
                for o in movers:
                    ro.field.replace(o, before[o])
                return False, f"{m}: {why}"
        for m in movers:
            task = self.sc.vehicles[m]
            p, v, a = sampled[m]
            ro.traj[m] = VehicleTrajectory(m, task.type_name, task.vehicle, ro.grid.copy(), p, v, a)
        return True, f", slowed x{scale:.2f}" if scale > 1.0 else ""

    def undo(self, saved: dict[str, VehicleTrajectory]) -> None:
        for name, tr in saved.items():
            self.ro.traj[name] = tr
            self.ro.field.replace(name, tr.position_at(self.ro.field.t_s))


def joint_moves(
    scenario,
    plan: Plan,
    *,
    wrench_provider: Callable,
    extent_provider: Callable | None = None,
    options: JointOptions = JointOptions(),
    progress: Callable | None = None,
) -> JointResult:
    """Rounds of joint moves (see module) until a round finds none, ``max_rounds`` or ``max_solves``;
    returns the shortest plan that passed ``proxplan.verify.verify_plan`` (the input plan when none
    was shorter)."""
    from proxplan.verify import verify_plan

    jm = _Joint(scenario, plan, options, wrench_provider, extent_provider)
    ro = jm.ro
    dt = float(ro.plan.dt_s)
    start = best_ms = makespan_of(plan)
    best, log = plan, []
    for rnd in range(options.max_rounds):
        M = makespan_of(ro.plan_now())
        found = False
        for f in options.fractions:
            if jm.solves >= jm.max_solves:
                break
            latest = [n for n in jm.movable if arrival_s(ro.traj[n]) > M - dt / 2]
            lo = max([jm.bound[n] for n in latest] + [ro.goal_free_s(n) + 0.1 for n in latest])
            T = lo + f * (M - lo)
            if T > M - 2 * dt:
                log.append(f"round {rnd + 1}: the latest vehicles are near their bound")
                break
            saved = dict(ro.traj)
            ok, why, moved = jm.round_at(T, progress)
            if ok:
                candidate = ro.plan_now()
                bad = verify_plan(candidate, scenario)
                why = f"verifier rejected ({bad[0]})" if bad else why
                ok = not bad
            if not ok:
                jm.undo({m: saved[m] for m in moved})
                log.append(f"round {rnd + 1} at {T:.2f} s: {why}")
                continue
            ms = makespan_of(candidate)
            log.append(f"round {rnd + 1}: makespan {M:.2f} -> {ms:.2f} s ({why})")
            if ms < best_ms - 1e-9:
                best, best_ms, found = candidate, ms, True
            break
        if not found:
            break
    improved = best_ms < start - 1e-9
    message = (
        f"joint moves (at most {options.max_movers} vehicles together, {jm.solves} IPOPT problems, "
        f"{jm.iterations} iterations): "
        + (f"makespan {start:.2f} s -> {best_ms:.2f} s, verified" if improved else "no verified shorter plan")
    )
    return JointResult(best, improved, message, jm.solves, jm.iterations, tuple(log))
