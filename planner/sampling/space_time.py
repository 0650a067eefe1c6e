"""OMPL space-time sampling planner for one vehicle against already-planned (moving) vehicles.

State space: R^3 x time, as an OMPL ``RealVectorStateSpace(4)`` with coordinates (x, y, z, tau),
m, where tau = v_ref t (m) so that the Euclidean metric used for nearest neighbours weighs a second
like ``v_ref`` metres. A Python ``MotionValidator`` makes the space directed: a motion is valid only
forward in time, no faster than the vehicle's jerk-limited rest-to-rest time over its length
(:class:`proxplan.planner.timing.DurationTable`), and with every intermediate state (at most
``check_step_m`` / ``check_step_s`` apart, linear interpolation) valid for the
:class:`proxplan.planner.checks.constraints.ConflictChecker` (workspace, inflated obstacles, separation, downwash
cutoffs of the other vehicles at that time).

Planner: OMPL ``RRT`` with goal bias. The goal is a set of goal states at the goal position, one
per candidate arrival time from which holding the goal (or flying the dock approach and holding the
dock) stays valid. RRT is chosen because it only ever checks motions from the tree towards new
states (forward in time), which a directed space needs; RRTConnect grows a second tree backwards
from a goal whose arrival time is unknown. After the first solution, OMPL's ``PathSimplifier``
shortcuts the path (shortcuts are checked with the same directed validator) and a time-compression
pass moves every waypoint to its earliest valid time, which minimises flight time along the path.
Runs are reproducible: every solve seeds the generators of the OMPL objects it creates from its
own seed (:func:`proxplan.planner.sampling.termination.seed_search`: the same search gives the same
path in any process, whatever was planned before in it), and every solve ends after a fixed
number of RRT iterations (a Python ``PlannerTerminationCondition``), not after a wall time, so the
random sequence does not depend on the machine's load (a generous CPU-time cap of the process remains
as a safety net only: a wall-time cap made results depend on how loaded the shared machine was).

Objective: among ``candidates`` RRT solutions (and in every shortcut choice) the planner keeps the
one with the lowest arrival time + ``usage_weight_s`` x predicted authority-usage integral, the
prediction being the cost map's usage grid of the sources above (``ConflictChecker.predicted_usage``).
"""

from __future__ import annotations

import math

import numpy as np

from proxplan.physics import KinematicLimits
from proxplan.planner.checks.constraints import ConflictChecker
from proxplan.planner.checks.validity import BatchChecker
from proxplan.planner.sampling.roadmap import roadmap_nodes, roadmap_search
from proxplan.planner.sampling.spec import GoalSpec, SamplingOptions, SpaceTimePath
from proxplan.planner.sampling.termination import IterationBudget, seed_search
from proxplan.planner.timing.durations import DurationTable, duration_table
from proxplan.planner.timing.segments import ruckig_segment


class _Planner:
    def __init__(self, checker: ConflictChecker, limits: KinematicLimits, horizon_s: float, opts: SamplingOptions):
        self.checker = checker
        self.limits = limits
        self.horizon_s = horizon_s
        self.opts = opts
        self.v_ref = max(0.25, opts.time_scale_factor * limits.max_speed_mps)  # tau = v_ref t
        self.v_plan = opts.planning_speed_factor * limits.max_speed_mps
        self.durations = duration_table(limits)
        self.iterations: list[int] = []
        self.batch = BatchChecker.from_checker(checker)

    # -- motion checks ---------------------------------------------------------------------
    def motion_ok(self, p1, t1: float, p2, t2: float, *, exclude: str | None = None, strict: bool = True) -> bool:
        """Directed motion check: forward in time, not faster than allowed, every state valid.

        ``strict``: the duration must cover a jerk-limited rest-to-rest motion (used on the final
        path); otherwise only the planning speed ``planning_speed_factor x max speed`` is enforced
        (used inside the RRT search, whose short edges are later merged by simplification)."""
        dt = t2 - t1
        if dt <= 0.0:
            return False
        dx, dy, dz = p2[0] - p1[0], p2[1] - p1[1], p2[2] - p1[2]
        dist = math.sqrt(dx * dx + dy * dy + dz * dz)
        if strict:
            if dt < self.durations.duration_s(dist) - 1e-9:
                return False
            return self.timed_segment_ok(p1, t1, p2, t2, self.limits, exclude=exclude, count=exclude is None)
        if dist > self.v_plan * dt:
            return False
        n = max(1, int(math.ceil(max(dist / self.opts.check_step_m, dt / self.opts.check_step_s))))
        if n == 1:
            return self.checker.valid(p2[0], p2[1], p2[2], t2)
        f = np.arange(1, n + 1) / n
        xyz = np.column_stack([p1[0] + f * dx, p1[1] + f * dy, p1[2] + f * dz])
        return self.batch.all_valid(xyz, t1 + f * dt, count=True)

    def timed_segment_ok(
        self, p1, t1: float, p2, t2: float, limits: KinematicLimits, *, exclude: str | None = None, count: bool = False
    ) -> bool:
        """Check the exact Ruckig segment (rest to rest, at least t2 - t1 long) that
        :func:`proxplan.planner.timing.time_parameterize` will fly, state by state."""
        dt = t2 - t1
        p1 = np.asarray(p1, dtype=float)
        p2 = np.asarray(p2, dtype=float)
        dist = float(np.linalg.norm(p2 - p1))
        n = max(1, int(math.ceil(max(dist / self.opts.check_step_m, dt / self.opts.check_step_s))))
        taus = dt * np.arange(1, n + 1) / n
        if dist > 1e-9:
            traj = ruckig_segment(p1, p2, limits, minimum_duration_s=dt)
            if traj.duration > dt + 1e-6:
                return False
            xyz = np.array([traj.at_time(float(tau))[0] for tau in taus])
        else:
            xyz = np.repeat(p1[None, :], n, axis=0)
        return self.batch.all_valid(xyz, t1 + taus, exclude=exclude, count=count)

    def hold_ok_from(self, p, t_from: float, t_until: float, *, exclude: str | None = None) -> bool:
        step = self.opts.hold_check_step_s
        n = max(1, int(math.ceil((t_until - t_from) / step)))
        t = t_from + step * np.arange(n + 1)
        return self.batch.all_valid(np.repeat(np.asarray(p, dtype=float)[None, :3], n + 1, axis=0), t, exclude=exclude)

    def earliest_hold_s(self, p, t_until: float, *, exclude: str | None = None) -> float:
        """Earliest time from which position ``p`` stays valid until ``t_until``; inf if never."""
        step = self.opts.hold_check_step_s
        n = int(math.ceil(t_until / step))
        t = step * np.arange(n + 1)
        static, code = self.batch.conflict_codes(
            np.repeat(np.asarray(p, dtype=float)[None, :3], n + 1, axis=0), t, exclude=exclude
        )
        bad = np.nonzero((static >= 0) | (code >= 0))[0]
        last_bad = int(bad[-1]) if bad.size else -1
        if last_bad == n:
            return math.inf
        return (last_bad + 1) * step

    def tail_ok(self, goal: GoalSpec, t_arrive: float) -> tuple[bool, float]:
        """Whether the dock approach from arrival time ``t_arrive`` is valid; its end time, s."""
        lim = goal.tail_limits or self.limits
        table = self.durations if goal.tail_limits is None else duration_table(goal.tail_limits)
        p, t = goal.position_m, t_arrive
        for q in goal.tail:
            d = float(np.linalg.norm(q - p))
            t2 = t + table.duration_s(d)
            if not self.timed_segment_ok(p, t, q, t2, lim, exclude=goal.tail_exempt):
                return False, t2
            p, t = q, t2
        return True, t

    # -- goal arrival times --------------------------------------------------------------------
    def goal_times(self, start, goal: GoalSpec) -> list[float]:
        t_min = self.durations.duration_s(float(np.linalg.norm(goal.position_m - start)))
        end_p = goal.tail[-1] if goal.tail else goal.position_m
        hold_from = self.earliest_hold_s(end_p, goal.hold_until_s, exclude=goal.tail_exempt)
        times = []
        t = max(t_min, self.opts.goal_time_step_s)
        step = self.opts.goal_time_step_s
        while t <= self.horizon_s:
            if goal.tail:
                ok, t_end = self.tail_ok(goal, t)
                ok = ok and t_end >= hold_from
            else:
                ok = t >= hold_from
            if ok:
                times.append(t)
            t += step
        return times

    # -- direct paths (before the search) ---------------------------------------------------------
    def direct(self, start: np.ndarray, goal: GoalSpec) -> SpaceTimePath | None:
        """Earliest arrival over a small roadmap with waits (:func:`proxplan.planner.sampling.roadmap.roadmap_search`);
        None when the goal cannot be reached that way (the RRT search follows)."""
        if goal.tail:
            return None
        end = np.asarray(goal.position_m, dtype=float)
        hold_from = self.earliest_hold_s(end, goal.hold_until_s)
        if not math.isfinite(hold_from):
            return None
        start = np.asarray(start, dtype=float)
        found = None
        for scale, wait_s in ((1.0, 8.0), (2.0, 20.0)):  # a wider, more patient second try
            found = roadmap_search(
                self.batch,
                self.limits,
                self.durations,
                roadmap_nodes(
                    start,
                    end,
                    self.checker.boxes,
                    dodge_m=self.opts.dodge_m * scale,
                    clearance_m=self.opts.detour_clearance_m,
                ),
                hold_from_s=hold_from,
                horizon_s=self.horizon_s,
                step_s=self.opts.direct_delay_step_s,
                hold_step_s=self.opts.hold_check_step_s,
                max_wait_s=wait_s,
            )
            if found is not None:
                break
        if found is None:
            return None
        pts, ts = found
        return SpaceTimePath(pts, ts, {"rrt_vertices": 0, "direct": True, "objective_s": self.objective(pts, ts)})

    def _exposure_samples(self, p: np.ndarray, t: np.ndarray) -> float:
        """Predicted usage integral (usage x s) of a motion sampled at times ``t`` (M,), s."""
        if t.size < 2:
            return 0.0
        u = [self.checker.predicted_usage(q[0], q[1], q[2], float(tt)) for q, tt in zip(p, t)]
        return float(np.trapezoid(u, t))

    # -- OMPL search ----------------------------------------------------------------------------
    def solve(self, start: np.ndarray, goal: GoalSpec, seed: int) -> SpaceTimePath | None:
        from ompl import base as ob
        from ompl import geometric as og
        from ompl import util as ou

        ou.setLogLevel(ou.LogLevel.LOG_ERROR)
        seed_search(seed)  # before any OMPL object of this search: its draws depend on seed alone
        chk = self.checker
        v_ref = self.v_ref
        space = ob.RealVectorStateSpace(4)
        bounds = ob.RealVectorBounds(4)
        for i in range(3):
            bounds.setLow(i, chk.lo[i])
            bounds.setHigh(i, chk.hi[i])
        bounds.setLow(3, 0.0)
        bounds.setHigh(3, self.horizon_s * v_ref)
        space.setBounds(bounds)
        si = ob.SpaceInformation(space)
        planner_self = self

        class DirectedMotion(ob.MotionValidator):
            def checkMotion(self, s1, s2, *args):  # noqa: N802 (OMPL name)
                return planner_self.motion_ok(
                    (s1[0], s1[1], s1[2]),
                    s1[3] / v_ref,
                    (s2[0], s2[1], s2[2]),
                    s2[3] / v_ref,
                    strict=planner_self.opts.strict_search,
                )

        validator = DirectedMotion(si)
        si.setMotionValidator(validator)
        si.setStateValidityChecker(lambda s: chk.valid(s[0], s[1], s[2], s[3] / v_ref))
        si.setup()

        def state(p, t):
            s = space.allocState()
            s[0], s[1], s[2], s[3] = float(p[0]), float(p[1]), float(p[2]), float(t * v_ref)
            return s

        direct = self.direct(start, goal) if self.opts.direct_first else None
        if direct is not None:
            t_free = self.durations.duration_s(float(np.linalg.norm(goal.position_m - start)))
            arrival = float(direct.times_s[-1])
            if arrival <= t_free + self.opts.direct_accept_slack_s or arrival <= self.opts.direct_accept_ratio * t_free:
                return direct
        times = self.goal_times(start, goal)
        if not times:
            return direct
        pdef = ob.ProblemDefinition(si)
        pdef.addStartState(state(start, 0.0))
        goals = ob.GoalStates(si)
        for t in times:
            goals.addState(state(goal.position_m, t))
        goals.setThreshold(1e-6)
        pdef.setGoal(goals)
        best = None
        for _ in range(self.opts.candidates):  # a fixed count keeps runs reproducible
            pdef.clearSolutionPaths()
            planner = og.RRT(si)
            planner.setRange(self.opts.range_m)
            planner.setGoalBias(self.opts.goal_bias)
            planner.setProblemDefinition(pdef)
            planner.setup()
            counter = IterationBudget(self.opts.max_iterations, 4.0 * self.opts.time_budget_s)
            planner.solve(ob.PlannerTerminationCondition(counter))
            self.iterations.append(counter.calls)
            if not pdef.hasExactSolution():
                continue
            path = pdef.getSolutionPath()
            simplifier = og.PathSimplifier(si)
            simplifier.reduceVertices(path)
            pts = np.array([[path.getState(i)[j] for j in range(3)] for i in range(path.getStateCount())])
            ts = np.array([path.getState(i)[3] / v_ref for i in range(path.getStateCount())])
            pts, ts = self.compress(pts, ts, goal)
            cost = self.objective(pts, ts)
            if best is None or cost < best.info["objective_s"]:
                best = SpaceTimePath(pts, ts, {"rrt_vertices": int(path.getStateCount()), "objective_s": cost})
        if direct is not None and (best is None or direct.info["objective_s"] <= best.info["objective_s"]):
            return direct
        return best

    def compress(self, pts: np.ndarray, ts: np.ndarray, goal: GoalSpec) -> tuple[np.ndarray, np.ndarray]:
        """Greedy space-time shortcut with earliest times.

        From the current waypoint, try every later waypoint j with a strict (jerk-limited
        rest-to-rest, exact Ruckig profile) straight motion at the earliest valid time within a
        window of ``12 x 0.25 s`` after its minimum duration (waiting lets another vehicle pass);
        keep the j with the earliest lower bound on the final arrival (time at j + minimum time
        from j to the goal). The last waypoint must also allow the arrival (dock approach, hold).
        Without any valid candidate, the search's own schedule for the next waypoint is kept.
        """
        step = self.opts.compress_step_s * 5
        window = 12
        out_p, out_t = [pts[0]], [float(ts[0])]
        i, last = 0, len(pts) - 1
        end_p = pts[last]
        while i < last:
            chosen = None
            best_eta = math.inf
            for j in range(last, i, -1):
                lb = out_t[-1] + self.durations.duration_s(float(np.linalg.norm(pts[j] - out_p[-1])))
                eta_floor = lb + self.durations.duration_s(float(np.linalg.norm(end_p - pts[j])))
                if eta_floor >= best_eta:
                    continue
                t = lb
                for _ in range(window + 1):
                    if self.motion_ok(out_p[-1], out_t[-1], pts[j], t) and (
                        self._arrival_ok(goal, t) if j == last else self._rejoin_ok(pts[j], t, float(ts[j]))
                    ):
                        eta = t + self.durations.duration_s(float(np.linalg.norm(end_p - pts[j])))
                        eta += self.opts.usage_weight_s * self.exposure(out_p[-1], out_t[-1], pts[j], t)
                        if eta < best_eta:
                            best_eta, chosen = eta, (j, t)
                        break
                    t += step
            if chosen is None:
                # fall back to the search's own schedule from here: wait at this waypoint until the
                # search's time for it, then fly to the next waypoint at the search's time
                if out_t[-1] < float(ts[i]) - 1e-9:
                    out_p.append(pts[i])
                    out_t.append(float(ts[i]))
                j = i + 1
                lb = out_t[-1] + self.durations.duration_s(float(np.linalg.norm(pts[j] - out_p[-1])))
                chosen = (j, max(float(ts[j]), lb))
            out_p.append(pts[chosen[0]])
            out_t.append(chosen[1])
            i = chosen[0]
        return np.array(out_p), np.array(out_t)

    def exposure(self, p1, t1: float, p2, t2: float) -> float:
        """Predicted authority-usage integral along a straight motion, usage x s (objective term)."""
        dt = t2 - t1
        if dt <= 0.0:
            return 0.0
        n = max(2, int(math.ceil(dt / self.opts.check_step_s)))
        total = 0.0
        for k in range(n):
            f = (k + 0.5) / n
            total += self.checker.predicted_usage(
                p1[0] + f * (p2[0] - p1[0]), p1[1] + f * (p2[1] - p1[1]), p1[2] + f * (p2[2] - p1[2]), t1 + f * dt
            )
        return total * dt / n

    def objective(self, pts: np.ndarray, ts: np.ndarray) -> float:
        """Arrival time + ``usage_weight_s`` x predicted usage integral of a waypoint path, s."""
        return float(ts[-1]) + self.opts.usage_weight_s * sum(
            self.exposure(pts[k], ts[k], pts[k + 1], ts[k + 1]) for k in range(len(pts) - 1)
        )

    def _rejoin_ok(self, p, t: float, t_search: float) -> bool:
        """Whether waiting at ``p`` from ``t`` until the search's own time ``t_search`` is valid,
        so that the search's schedule can always be resumed from there."""
        return t >= t_search or self.hold_ok_from(p, t, t_search)

    def _arrival_ok(self, goal: GoalSpec, t: float) -> bool:
        end_p = goal.tail[-1] if goal.tail else goal.position_m
        if goal.tail:
            ok, t_end = self.tail_ok(goal, t)
            if not ok:
                return False
        else:
            t_end = t
        return self.hold_ok_from(end_p, t_end, goal.hold_until_s, exclude=goal.tail_exempt)


def plan_space_time(
    checker: ConflictChecker,
    start_m: np.ndarray,
    goal: GoalSpec,
    limits: KinematicLimits,
    *,
    horizon_s: float,
    seed: int = 0,
    options: SamplingOptions = SamplingOptions(),
) -> SpaceTimePath | None:
    """Plan one vehicle from ``start_m`` (3,) at t = 0 to ``goal``; None when no path was found.

    The returned waypoints end at ``goal.position_m`` followed by the ``goal.tail`` waypoints, with
    rest-to-rest minimum times on the tail.
    """
    planner = _Planner(checker, limits, horizon_s, options)
    path = planner.solve(np.asarray(start_m, dtype=float), goal, seed)
    if path is None:
        return None
    pts, ts = list(path.waypoints_m), list(path.times_s)
    table = planner.durations if goal.tail_limits is None else DurationTable(goal.tail_limits)
    for q in goal.tail:
        ts.append(ts[-1] + table.duration_s(float(np.linalg.norm(q - pts[-1]))))
        pts.append(np.asarray(q, dtype=float))
    return SpaceTimePath(np.array(pts), np.array(ts), path.info)


def start_conflict(checker: ConflictChecker, start_m: np.ndarray) -> str | None:
    """The constraint the start state violates at t = 0, or None."""
    return checker.conflict(float(start_m[0]), float(start_m[1]), float(start_m[2]), 0.0, resting=True)
