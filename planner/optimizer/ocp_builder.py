"""The Opti problem of :mod:`proxplan.planner.optimizer.ocp` while it is assembled: decision
variables and the exact triple-integrator dynamics of every moving vehicle, kinematic limits,
workspace, obstacles (side selection from the warm start), dock boundary conditions and approach,
pairwise separation and the model's invalid zone (S0 II-A). World frame, z up; m, s."""

from __future__ import annotations

from typing import Any

import numpy as np

from proxplan.physics import VALIDITY_FACTOR_L
from proxplan.planner.optimizer.ocp_problem import OcpAgent, OcpProblem

INVALID_ZONE_SMOOTHING_M = 0.01  # largest conservatism of the smoothed invalid-zone constraint, m


def _warm(values: np.ndarray | None, default: np.ndarray, n: int) -> np.ndarray:
    if values is None:
        return np.tile(np.asarray(default, float), (n + 1, 1))
    arr = np.asarray(values, float)
    if arr.shape != (n + 1, 3):
        raise ValueError(f"warm start must have shape ({n + 1}, 3), got {arr.shape}")
    return arr


def _check_points_warm(nodes: np.ndarray) -> np.ndarray:
    """Warm positions at the check points: nodes (n+1) then midpoints (n), shape (2n+1, 3)."""
    return np.vstack([nodes, 0.5 * (nodes[:-1] + nodes[1:])])


class OcpBuilder:
    """Holds the Opti problem while it is assembled (one call of :func:`proxplan.planner.optimizer.ocp.build_and_solve`): its
    variables, dynamics, kinematic limits, workspace, obstacles, dock approach and pair constraints;
    the authority constraints are added by :mod:`proxplan.planner.optimizer.ocp_authority`, the solve
    by :mod:`proxplan.planner.optimizer.ocp_solve`."""

    def __init__(self, problem: OcpProblem):
        import casadi as ca

        self.ca = ca
        self.pb = problem
        self.n = problem.n_intervals
        self.opti = ca.Opti()
        n = self.n
        self.n_approach = problem.approach_intervals if problem.fixed_duration_s is None else 0
        self.n_free = n - self.n_approach  # intervals of the first (free-flight) phase
        if problem.fixed_duration_s is not None:
            self.T = problem.fixed_duration_s
            self.phase_T: list = []
            self.h_row = ca.DM.ones(1, n) * (self.T / n)
        elif self.n_approach > 0:  # two phases, each with its own free duration, s
            self.phase_T = [self.opti.variable(), self.opti.variable()]
            self.T = self.phase_T[0] + self.phase_T[1]
            self.h_row = ca.horzcat(
                ca.repmat(self.phase_T[0] / self.n_free, 1, self.n_free),
                ca.repmat(self.phase_T[1] / self.n_approach, 1, self.n_approach),
            )
        else:
            self.phase_T = [self.opti.variable()]
            self.T = self.phase_T[0]
            self.h_row = ca.repmat(self.T / n, 1, n)
        self.warm_t = problem.warm_times_s()  # (n+1,) s
        self.agents = {a.name: a for a in problem.agents}
        self.names = [a.name for a in problem.agents]
        self.X: dict[str, Any] = {}  # casadi MX states (9, n+1)
        self.U: dict[str, Any] = {}  # casadi MX jerk inputs (3, n)
        self.Q: dict[str, Any] = {}  # casadi MX positions at check points (3, 2n+1)
        self.Qw: dict[str, np.ndarray] = {}  # warm positions at check points (2n+1, 3)
        self.exempt: dict[tuple[str, str], np.ndarray] = {}  # dock pair -> (2n+1,) bool
        self.cost = problem.weights.time * self.T
        self.linear_groups: list[dict] = []

    # ---------------------------------------------------------------- vehicles
    def add_vehicles(self) -> None:
        ca, opti, n, pb = self.ca, self.opti, self.n, self.pb
        h = ca.repmat(self.h_row, 3, 1)  # (3, n) interval lengths, s
        if self.phase_T:
            opti.subject_to(opti.bounded(0.1 * pb.warm_duration_s, self.T, pb.max_duration_s))
            bounds = [0, self.n_free, n] if len(self.phase_T) == 2 else [0, n]
            shrink = min(1.0, pb.max_duration_s / pb.warm_duration_s)
            for T_k, k_lo, k_hi in zip(self.phase_T, bounds[:-1], bounds[1:]):
                warm_k = float(self.warm_t[k_hi] - self.warm_t[k_lo])
                opti.subject_to(T_k >= 0.05 * warm_k)
                opti.set_initial(T_k, shrink * warm_k)
        for a in pb.agents:
            wp = (
                _warm(a.warm_position_m, a.start_m, n)
                if a.moving
                else np.tile(np.asarray(a.start_m, float), (n + 1, 1))
            )
            self.Qw[a.name] = _check_points_warm(wp)
            if not a.moving:
                if a.fixed_path_m is not None:  # a known trajectory at the check points
                    self.Qw[a.name] = np.asarray(a.fixed_path_m, float).reshape(2 * n + 1, 3)
                self.Q[a.name] = ca.DM(self.Qw[a.name].T)
                continue
            X, U = opti.variable(9, n + 1), opti.variable(3, n)
            self.X[a.name], self.U[a.name] = X, U
            p, v, ac = X[0:3, :], X[3:6, :], X[6:9, :]
            p0, v0, a0 = p[:, :-1], v[:, :-1], ac[:, :-1]
            # multiple shooting with the exact triple-integrator step
            opti.subject_to(p[:, 1:] == p0 + h * v0 + h**2 / 2 * a0 + h**3 / 6 * U)
            opti.subject_to(v[:, 1:] == v0 + h * a0 + h**2 / 2 * U)
            opti.subject_to(ac[:, 1:] == a0 + h * U)
            # midpoint positions are lifted into variables: the pair constraints then touch 3
            # variables per vehicle instead of 12, which keeps the Hessian sparse
            mid_p = opti.variable(3, n)
            opti.subject_to(mid_p == p0 + h / 2 * v0 + h**2 / 8 * a0 + h**3 / 48 * U)
            opti.set_initial(mid_p, self.Qw[a.name][n + 1 :].T)
            mid_v = v0 + h / 2 * a0 + h**2 / 8 * U
            self.Q[a.name] = ca.horzcat(p, mid_p)
            opti.subject_to(X[:, 0] == ca.vertcat(ca.DM(np.asarray(a.start_m, float)), ca.DM.zeros(6)))
            opti.subject_to(X[3:9, n] == 0)
            if a.goal_m is not None and a.dock_with is None:
                opti.subject_to(p[:, n] == ca.DM(np.asarray(a.goal_m, float)))
            m = pb.kinematic_margin
            opti.subject_to(ca.sum1(ca.horzcat(v, mid_v) ** 2) <= (m * a.max_speed_mps) ** 2)
            opti.subject_to(ca.sum1(ac**2) <= (m * a.max_accel_mps2) ** 2)
            opti.subject_to(ca.sum1(U**2) <= (m * a.max_jerk_mps3) ** 2)
            rb = a.body_radius_m
            grow = np.array([rb, rb, 0.0]) + pb.chord_margin_m
            lo = np.asarray(pb.workspace_min_m, float) + grow
            hi = np.asarray(pb.workspace_max_m, float) - grow
            Q = self.Q[a.name]
            opti.subject_to(opti.bounded(ca.repmat(ca.DM(lo), 1, 2 * n + 1), Q, ca.repmat(ca.DM(hi), 1, 2 * n + 1)))
            self.cost += pb.weights.smoothness * ca.sum2(self.h_row * ca.sum1((U / a.max_jerk_mps3) ** 2))
            # warm start
            wv = _warm(a.warm_velocity_mps, np.zeros(3), n)
            wa = _warm(a.warm_acceleration_mps2, np.zeros(3), n)
            opti.set_initial(X, np.vstack([wp.T, wv.T, wa.T]))
            wj = np.diff(wa, axis=0) / np.maximum(np.diff(self.warm_t), 1e-6)[:, None]
            opti.set_initial(U, wj.T)
            self._obstacles(a, Q, self.Qw[a.name])
        for a in pb.agents:  # dock boundary conditions (the partner may itself be moving)
            if a.moving and a.dock_with is not None:
                partner = self.Q[a.dock_with][:, n]
                opti.subject_to(self.Q[a.name][:, n] == partner + ca.DM(np.asarray(a.dock_offset_m, float)))
                self._dock_approach(a)

    def _obstacles(self, a: OcpAgent, Q, Qw: np.ndarray) -> None:
        pb = self.pb
        grow_xy = a.body_radius_m + pb.obstacle_margin_m + pb.chord_margin_m
        grow = np.array([grow_xy, grow_xy, pb.obstacle_margin_m + pb.chord_margin_m])
        for lo_b, hi_b in pb.obstacles:
            blo, bhi = np.asarray(lo_b, float) - grow, np.asarray(hi_b, float) + grow
            outside = np.hstack([blo - Qw, Qw - bhi])  # (2n+1, 6): -x,-y,-z then +x,+y,+z faces
            face = np.argmax(outside, axis=1)
            near = outside[np.arange(len(face)), face] < 3.0
            for f in range(6):
                ks = np.flatnonzero((face == f) & near).tolist()
                if not ks:
                    continue
                axis = f % 3
                if f >= 3:
                    self.opti.subject_to(Q[axis, ks] >= bhi[axis])
                else:
                    self.opti.subject_to(Q[axis, ks] <= blo[axis])

    def _dock_approach(self, a: OcpAgent) -> None:
        """On the final approach (warm start within ``dock_reach_m`` of the dock point) the docker
        stays on the dock axis, on the near side of the dock point, at reduced speed."""
        ca, opti = self.ca, self.opti
        assert a.dock_with is not None
        off = np.asarray(a.dock_offset_m, float)
        u = off / max(np.linalg.norm(off), 1e-9)
        rel_w = self.Qw[a.name] - self.Qw[a.dock_with] - off
        exempt = np.linalg.norm(rel_w, axis=1) <= a.dock_reach_m
        if self.n_approach > 0:  # the approach phase: nodes from n_free on and its midpoints
            exempt[self.n_free : self.n + 1] = True
            exempt[self.n + 1 + self.n_free :] = True
        self.exempt[(a.name, a.dock_with)] = exempt
        ks = np.flatnonzero(exempt).tolist()
        if not ks:
            return
        rel = self.Q[a.name][:, ks] - self.Q[a.dock_with][:, ks] - ca.DM(off)
        along = ca.mtimes(ca.DM(u).T, rel)
        perp = rel - ca.mtimes(ca.DM(u), along)
        opti.subject_to(ca.sum1(perp**2) <= 0.03**2)
        # not at the final node: there the dock equality already fixes along = 0 (a second, active
        # constraint with the same gradient breaks LICQ and IPOPT's multipliers diverge)
        not_final = [i for i, k in enumerate(ks) if k != self.n]
        if not_final:
            opti.subject_to(along[:, not_final] >= 0)
            if a.dock_approach_m > 0.0:  # on the segment from the approach point A to the dock point D
                opti.subject_to(along[:, not_final] <= a.dock_approach_m)
        nodes = [k for k in ks if k <= self.n]
        if nodes:
            v = self.X[a.name][3:6, nodes]
            vmax = self.pb.dock_speed_factor * a.max_speed_mps
            opti.subject_to(ca.sum1(v**2) <= vmax**2)

    def is_exempt(self, x: str, y: str) -> np.ndarray:
        m = np.zeros(2 * self.n + 1, dtype=bool)
        for key in ((x, y), (y, x)):
            if key in self.exempt:
                m |= self.exempt[key]
        return m

    def may_move(self, a: OcpAgent) -> np.ndarray:
        """(2n+1,) bool per check point (nodes, then midpoints): True where vehicle ``a`` may move.
        An optimised vehicle may move anywhere but at its fixed start and end nodes; a held one where
        its known path moves faster than the verifier's rest speed (0.05 m/s)."""
        n = self.n
        if a.moving:
            mask = np.ones(2 * n + 1, dtype=bool)
            mask[[0, n]] = False
            return mask
        q = self.Qw[a.name]
        order = np.empty((2 * n + 1, 3))  # time order: node 0, mid 0, node 1, ...
        order[0::2], order[1::2] = q[: n + 1], q[n + 1 :]
        half = np.repeat(0.5 * np.maximum(np.diff(self.warm_t), 1e-6), 2)  # (2n,) s between check points
        speed = np.linalg.norm(np.diff(order, axis=0), axis=1) / half
        moving_t = np.zeros(2 * n + 1, dtype=bool)
        moving_t[:-1] |= speed >= 0.05
        moving_t[1:] |= speed >= 0.05
        return np.concatenate([moving_t[0::2], moving_t[1::2]])

    # ---------------------------------------------------------------- pairs
    def add_pairs(self) -> None:
        ca, opti, pb = self.ca, self.opti, self.pb
        for i, ni in enumerate(self.names):
            for nj in self.names[i + 1 :]:
                ai, aj = self.agents[ni], self.agents[nj]
                if not (ai.moving or aj.moving):
                    continue
                exempt = self.is_exempt(ni, nj)
                rel_w = self.Qw[ni] - self.Qw[nj]
                dist_w = np.linalg.norm(rel_w, axis=1)
                sep0 = max(pb.min_separation_m, ai.body_radius_m + aj.body_radius_m) + pb.chord_margin_m
                # the tracking tube widens the separation wherever either vehicle may move (as verify does)
                sep = sep0 + pb.tube_m * (self.may_move(ai) | self.may_move(aj))  # (2n+1,) m
                ks = np.flatnonzero(~exempt & (dist_w < sep + pb.interaction_radius_m)).tolist()
                if ks:
                    diff = self.Q[ni][:, ks] - self.Q[nj][:, ks]
                    opti.subject_to(ca.sum1(diff**2) >= ca.DM(sep[ks] ** 2).T)
                if pb.invalid_zone_keep_out:
                    for s, t in ((ni, nj), (nj, ni)):
                        self._invalid_zone(s, t, exempt)

    def _invalid_zone(self, s: str, t: str, exempt: np.ndarray) -> None:
        """Keep target t out of source s's invalid zone, the cylinder 0 < dz <= 3 L_s, r < r_s + r_t
        (S0 II-A), grown by the chord margin and, wherever either may move, by the tracking tube (as
        the verifier). Outside the cylinder means max(g_below, g_beside, g_above) >= 0 with
        g_below = dz - depth, g_beside = r - radius, g_above = -dz - margin (m); the max is replaced
        by its smooth upper bound, the log-sum-exp with sharpness k (1/m), shifted down by its
        largest excess ln(3) / k:  LSE_k(g) - ln(3)/k >= 0  implies  max(g) >= 0, so the constraint
        is conservative by at most ln(3) / k = ``INVALID_ZONE_SMOOTHING_M`` near the cylinder's rim
        and exact far from it, and a path may pass from beside the zone to below it. (A
        super-ellipsoid enclosing the cylinder reached 19 % beyond it near the rim: a warm start
        that the sampling planner flew just under another vehicle's zone made 32-vehicle problems
        infeasible; side selection locked crossing paths to one side.)"""
        ca, opti, pb = self.ca, self.opti, self.pb
        src, tgt = self.agents[s], self.agents[t]
        eps = pb.chord_margin_m
        tube = pb.tube_m * (self.may_move(src) | self.may_move(tgt))  # (2n+1,) m
        depth = VALIDITY_FACTOR_L * src.vehicle.size_m + tube + eps  # (2n+1,) m
        radius = src.body_radius_m + tgt.body_radius_m + tube + eps  # (2n+1,) m
        rel_w = self.Qw[t] - self.Qw[s]
        dz_w, r_w = -rel_w[:, 2], np.hypot(rel_w[:, 0], rel_w[:, 1])
        near = ~exempt & (r_w < radius + 0.6) & (dz_w > -eps - 0.6) & (dz_w < depth + 0.6)
        ks = np.flatnonzero(near).tolist()
        if not ks:
            return
        k = np.log(3.0) / INVALID_ZONE_SMOOTHING_M  # 1/m
        rel = self.Q[t][:, ks] - self.Q[s][:, ks]
        dz = -rel[2, :]
        r = ca.sqrt(ca.sum1(rel[0:2, :] ** 2) + 1e-8)
        g = [dz - ca.DM(depth[ks]).T, r - ca.DM(radius[ks]).T, -dz - eps]
        top = ca.fmax(g[0], ca.fmax(g[1], g[2]))  # the shift keeps exp() finite; LSE is unchanged by it
        lse = top + ca.log(sum(ca.exp(k * (gi - top)) for gi in g)) / k
        opti.subject_to(lse >= INVALID_ZONE_SMOOTHING_M)
