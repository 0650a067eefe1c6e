"""The CasADi trajectory-optimisation problem (``Opti`` + IPOPT) of the optimised planner.

All moving vehicles are optimised jointly on one uniform time grid of ``n_intervals`` intervals over
a free common duration T (s), the makespan. Each moving vehicle is a triple integrator in the world
frame (z up) with state x = (p_m, v_mps, a_mps2) at the grid nodes and a piecewise-constant jerk
input j_mps3 per interval; multiple shooting with the exact discretisation of the integrator

    p+ = p + h v + h^2/2 a + h^3/6 j,   v+ = v + h a + h^2/2 j,   a+ = a + h j,   h = T / n

so the node states describe the continuous trajectory exactly. Hovering vehicles are constants.

Path constraints are imposed at *check points*: every node and every interval midpoint (the exact
midpoint position p + h/2 v + h^2/8 a + h^3/48 j), so nothing slips through between nodes:
start at rest, goal (absolute, or the dock partner's final position plus the dock offset) at rest;
speed / acceleration / jerk norms (the verifier's convention); workspace box shrunk by the body
radius; axis-aligned box obstacles by side selection from the warm start (the face the warm-start
point is furthest outside of); pairwise separation; the model's invalid zone (0 < dz <= 3 L of a
source with overlapping footprints, S0 II-A) enclosed by a smooth super-ellipsoid; a dock pair
on its final approach stays on the dock axis instead; and **authority usage <= authority_fraction**
for every vehicle: the disturbance wrench (F_z, tau_x, tau_y) on a target from each other vehicle
comes from the differentiable wrench table of ``proxplan.costmaps.map_store`` (the same numbers as
``proxplan.physics.disturbance``), is summed over sources and mapped through the inverse mixer of (S0-14)
(``proxplan.physics.authority.mixer_matrix``) to per-motor thrust changes, each bounded by
``fraction x headroom`` in its direction (DESIGN.md section 3) -- exactly ``usage <= fraction``
without a non-smooth max.

Objective: T + w_smooth * integral |j / j_max|^2 dt + w_exposure * integral of the summed squared
normalised motor changes (disturbance exposure).

The table's ``casadi.Function.bspline`` has no SX form. By default the table is therefore
linearised at the current offsets (value and Jacobian from its own CasADi function), the NLP is
SX-expanded and solved, and the linearisation is repeated a few times (sequential linearisation);
the exact table (MX, ``expand=False``) remains available. The final plan is always checked against
the model directly by :mod:`proxplan.verify.checks`. Problem data and results: :mod:`proxplan.planner.ocp_problem`.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np

from proxplan.physics import VALIDITY_FACTOR_L, normalised_motor_map
from proxplan.planner.ocp_problem import OcpAgent, OcpProblem, OcpSolution
from proxplan.planner.ocp_warm import repair_warm_start


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


INVALID_ZONE_SMOOTHING_M = 0.01  # largest conservatism of the smoothed invalid-zone constraint, m

_JACOBIANS: dict[int, tuple[Any, Any]] = {}  # id(fn) -> (fn, its jacobian); fn kept alive with it


def _jacobian(fn):
    """``fn.jacobian()``, built once per wrench function (about 1 s for a B-spline table)."""
    if id(fn) not in _JACOBIANS:
        _JACOBIANS[id(fn)] = (fn, fn.jacobian())
    return _JACOBIANS[id(fn)][1]


class _Builder:
    """Holds the Opti problem while it is assembled (one call of :func:`build_and_solve`)."""

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

    def _is_exempt(self, x: str, y: str) -> np.ndarray:
        m = np.zeros(2 * self.n + 1, dtype=bool)
        for key in ((x, y), (y, x)):
            if key in self.exempt:
                m |= self.exempt[key]
        return m

    def _may_move(self, a: OcpAgent) -> np.ndarray:
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
                exempt = self._is_exempt(ni, nj)
                rel_w = self.Qw[ni] - self.Qw[nj]
                dist_w = np.linalg.norm(rel_w, axis=1)
                sep0 = max(pb.min_separation_m, ai.body_radius_m + aj.body_radius_m) + pb.chord_margin_m
                # the tracking tube widens the separation wherever either vehicle may move (as verify does)
                sep = sep0 + pb.tube_m * (self._may_move(ai) | self._may_move(aj))  # (2n+1,) m
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
        tube = pb.tube_m * (self._may_move(src) | self._may_move(tgt))  # (2n+1,) m
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

    # ---------------------------------------------------------------- authority
    def add_authority(self) -> None:
        """Authority usage <= fraction at the check points. All offsets that share one wrench
        function (one vehicle-type pair) go through a single ``Function.map`` call; sparse
        selection matrices scatter the per-motor changes to (target, check point)."""
        ca, opti, pb, n = self.ca, self.opti, self.pb, self.n
        nq = 2 * n + 1
        # quadrature weights of the check points (nodes, then midpoints), s: node k gets a quarter of
        # each adjacent interval, a midpoint half of its own, so the exposure is a time integral
        # (a longer stay in a jet costs more; with one weight per check point instead, the two-phase
        # docking problem preferred to stretch its approach phase)
        h_row = self.h_row
        zero = ca.DM.zeros(1, 1)
        node_w = 0.25 * (ca.horzcat(zero, h_row) + ca.horzcat(h_row, zero))
        quad_w = ca.horzcat(node_w, 0.5 * h_row)  # (1, nq) s
        groups: dict[int, dict] = {}  # id(fn) -> {"fn", "offsets": [MX], "rows": [(target, ks)]}
        for nt in self.names:
            for ns in self.names:
                fn = pb.wrench_functions.get((ns, nt))
                if ns == nt or fn is None or not (self.agents[ns].moving or self.agents[nt].moving):
                    continue
                rel_w = self.Qw[nt] - self.Qw[ns]
                r_w = np.hypot(rel_w[:, 0], rel_w[:, 1])
                near = (r_w <= pb.interaction_radius_m) & (rel_w[:, 2] < 0.5)
                extent = pb.interaction_extent.get((ns, nt))
                if extent is not None:
                    dz_w = np.maximum(-rel_w[:, 2], 0.0)
                    near &= (r_w <= np.asarray(extent(dz_w)) + pb.extent_margin_m) & (rel_w[:, 2] < pb.extent_margin_m)
                if (ns, nt) in pb.dock_usage_functions:  # the approach: the model's envelope instead
                    near &= ~self._is_exempt(ns, nt)
                ks = np.flatnonzero(near)
                if ks.size == 0:
                    continue
                g = groups.setdefault(id(fn), {"fn": fn, "offsets": [], "rows": []})
                rel = self.Q[nt][:, ks.tolist()] - self.Q[ns][:, ks.tolist()]
                tube = pb.tube_m * (self._may_move(self.agents[ns]) | self._may_move(self.agents[nt]))[ks]
                if tube.any():  # worst point of the tracking tube, towards the axis (smooth), while either
                    # may move; none where both rest (e.g. at the goal), as in the verifier
                    r2 = rel[0, :] ** 2 + rel[1, :] ** 2
                    tube_row = ca.DM(tube).T
                    shrink = 1.0 - tube_row / ca.sqrt(r2 + tube_row**2 + 1e-12)
                    rel = ca.vertcat(rel[0, :] * shrink, rel[1, :] * shrink, rel[2, :])
                g["offsets"].append(rel)
                g["rows"].append((nt, ks))
        totals: dict[str, Any] = {}  # target -> casadi (4, nq) motor-thrust changes, N
        active: dict[str, np.ndarray] = {}
        self.linear_groups = []
        for g in groups.values():
            offsets = ca.horzcat(*g["offsets"])
            m_all = int(offsets.shape[1])
            if pb.linearize:
                # first-order model of the table about parameters O0: W0 + J (O - O0), re-linearised
                # by build_and_solve between solves (keeps the NLP SX-expandable)
                o0, w0, jac = opti.parameter(3, m_all), opti.parameter(3, m_all), opti.parameter(9, m_all)
                d = offsets - o0
                w = ca.vertcat(*[w0[i, :] + ca.sum1(jac[3 * i : 3 * i + 3, :] * d) for i in range(3)])
                self.linear_groups.append({"fn": g["fn"], "offsets": offsets, "o0": o0, "w0": w0, "jac": jac})
                self.cost += pb.proximal_weight * ca.sumsqr(d)
            else:
                w = g["fn"].map(m_all)(offsets)  # (3, M): F_z N, tau_x N m, tau_y N m
            col = 0
            for nt, ks in g["rows"]:
                m = int(ks.size)
                a_map, up, down = normalised_motor_map(self.agents[nt].vehicle)
                per_source = ca.mtimes(ca.DM(a_map), w[:, col : col + m])  # (4, m) motor changes, N
                # exposure per (source, target) pair: sum_k w_k |delta_f / headroom|^2 (pairwise
                # terms keep the Hessian sparse; the constraint below uses the sum over sources)
                scaled = per_source * ca.DM(np.outer(1.0 / np.minimum(up, down), np.ones(m)))
                self.cost += pb.weights.exposure * ca.dot(ca.sum1(scaled**2), quad_w[:, ks.tolist()])
                select = ca.DM.triplet(list(range(m)), ks.tolist(), ca.DM.ones(m), m, nq)
                contrib = ca.mtimes(per_source, select)  # (4, nq) N
                totals[nt] = contrib if nt not in totals else totals[nt] + contrib
                active.setdefault(nt, np.zeros(nq, dtype=bool))[ks] = True
                col += m
        approach = self._approach_usage(quad_w)  # target -> (columns, usage envelope (1, m))
        for nt in approach:
            if nt not in totals:  # the dock partner is the only source: bound its envelope alone
                cols, env = approach[nt]
                opti.subject_to(env <= pb.authority_fraction - 2e-4)
        for nt, total in totals.items():
            a_map, up, down = normalised_motor_map(self.agents[nt].vehicle)
            frac = np.full(nq, pb.authority_fraction * pb.authority_margin)
            frac[n] = pb.authority_fraction - 2e-4  # the final state is static: full fraction
            bg = self.agents[nt].background_wrench
            if bg is not None:  # sources outside the problem (fixed): a constant motor-thrust change, N
                bg_motor = a_map @ np.asarray(bg, float).reshape(3, nq)
                total = total + ca.DM(bg_motor)
                # where the background alone already uses the margin, allow what it uses (+0.01):
                # the optimised vehicle then may add little there; the verifier has the last word
                bg_usage = np.maximum((bg_motor / up[:, None]).max(axis=0), (-bg_motor / down[:, None]).max(axis=0))
                frac = np.maximum(frac, np.minimum(bg_usage + 0.01, pb.authority_fraction - 2e-4))
            for key, ex in self.exempt.items():
                if nt in key:
                    frac[ex] = pb.authority_fraction - 2e-4
            if nt in approach:  # the dock partner's envelope takes its share of the bound there
                env_cols, env = approach[nt]
                env_full = ca.mtimes(
                    env,
                    ca.DM.triplet(list(range(len(env_cols))), env_cols, ca.DM.ones(len(env_cols)), len(env_cols), nq),
                )
                alone = [k for k in env_cols if not active[nt][k]]
                if alone:
                    sel = [env_cols.index(k) for k in alone]
                    opti.subject_to(env[:, sel] <= pb.authority_fraction - 2e-4)
                cols = np.flatnonzero(active[nt]).tolist()
                room = ca.DM(frac[cols]).T - env_full[:, cols]  # (1, m) usage left for the other sources
                df = total[:, cols]
                # as vectors: an inequality between two matrices is a matrix (LMI) inequality in Opti
                opti.subject_to(ca.vec(df) <= ca.vec(ca.mtimes(ca.DM(up), room)))
                opti.subject_to(ca.vec(-df) <= ca.vec(ca.mtimes(ca.DM(down), room)))
                continue
            cols = np.flatnonzero(active[nt]).tolist()
            df = total[:, cols]
            opti.subject_to(opti.bounded(-ca.DM(np.outer(down, frac[cols])), df, ca.DM(np.outer(up, frac[cols]))))

    def _approach_usage(self, quad_w) -> dict[str, tuple[list[int], Any]]:
        """Dock pairs on their final approach (exempt check points): the target's authority usage
        from its dock partner is the model's envelope ``dock_usage_functions[(source, target)](dz)``
        (the extrapolated near field inside the invalid zone, as the verifier checks it) instead of
        the wrench table, which holds its first layer there. Adds the exposure of those points
        (4 motors x usage^2, the table's measure for a vertical force) and returns, per target,
        the check-point columns and the envelope values (1, m)."""
        ca, pb = self.ca, self.pb
        out: dict[str, tuple[list[int], Any]] = {}
        for (ns, nt), fn in pb.dock_usage_functions.items():
            if ns not in self.agents or nt not in self.agents:
                continue
            ks = np.flatnonzero(self._is_exempt(ns, nt)).tolist()
            if not ks:
                continue
            dz = self.Q[ns][2, ks] - self.Q[nt][2, ks]  # (1, m) m, target below the source
            env = fn.map(len(ks))(dz)
            self.cost += pb.weights.exposure * ca.dot(4.0 * env**2, quad_w[:, ks])
            out[nt] = (ks, env)
        return out

    # ---------------------------------------------------------------- solve
    def _linearize(self, evaluate) -> float:
        """Set the table's linear models about the offsets ``evaluate(expr)`` gives; returns the
        largest change of the offsets from the previous linearisation point, m."""
        ca = self.ca
        moved = 0.0
        for g in self.linear_groups:
            o = np.asarray(evaluate(g["offsets"]), float).reshape(3, -1)
            m = o.shape[1]
            fn = g["fn"]
            if "jac_map" not in g:
                g["val_map"] = fn.map(m)
                g["jac_map"] = _jacobian(fn).map(m)
            w = np.asarray(g["val_map"](o)).reshape(3, m)
            jac_flat = np.asarray(g["jac_map"](o, ca.DM.zeros(3, m))).reshape(3, 3 * m, order="F")
            # jacobian().map gives (3, 3 m): block k is d wrench / d offset at column k
            jac = jac_flat.reshape(3, m, 3).transpose(0, 2, 1)  # (out i, in j, point k)
            if "last" in g:
                moved = max(moved, float(np.abs(o - g["last"]).max()))
            g["last"] = o
            self.opti.set_value(g["o0"], o)
            self.opti.set_value(g["w0"], w)
            self.opti.set_value(g["jac"], jac.reshape(9, m))
        return moved

    def solve(self, progress, accept=None) -> OcpSolution:
        opti, pb = self.opti, self.pb
        opti.minimize(self.cost)
        opti.solver(
            "ipopt",
            {"expand": pb.expand or pb.linearize, "print_time": False},
            {
                "print_level": 0,
                "sb": "yes",
                "max_iter": pb.max_iterations,
                "max_cpu_time": pb.max_cpu_time_s,
                "max_wall_time": pb.max_wall_time_s or 2.0 * pb.max_cpu_time_s,
                "tol": 1e-6,
                "acceptable_tol": 1e-4,
                "mu_strategy": "adaptive",
                "hessian_approximation": pb.hessian,
                "linear_solver": pb.linear_solver,
            },
        )
        if progress is not None:
            progress(f"optimiser: {opti.nx} variables, {opti.ng} constraints")
        t0 = time.perf_counter()
        iterations = 0
        rounds = pb.max_linearizations if self.linear_groups else 1
        if self.linear_groups:
            self._linearize(lambda e: opti.debug.value(e, opti.initial()))
        best = None
        solves = 0
        for r in range(rounds):
            solves += 1
            try:
                sol = opti.solve()
                value, stats, ok = sol.value, sol.stats(), True
            except RuntimeError:
                value, stats, ok = opti.debug.value, opti.stats(), False
            iterations += int(stats.get("iter_count", 0))
            ok = ok and bool(stats.get("success", False))
            if not ok:
                if best is not None:  # keep the last converged linearisation round
                    value, stats, ok = best
                break
            best = (value, stats, ok)
            if not self.linear_groups or r == rounds - 1 or time.perf_counter() - t0 > pb.max_cpu_time_s:
                break
            if accept is not None and accept(
                self._collect(value, stats, ok, iterations, time.perf_counter() - t0, r + 1)
            ):
                break  # the caller's check (the verifier) already passes: no further linearisation
            moved = self._linearize(value)
            if progress is not None:
                progress(f"optimiser: linearisation {r + 1}: offsets moved {moved:.3f} m, {iterations} iterations")
            if moved < pb.linearization_tol:
                break
            opti.set_initial(sol.value_variables())
            opti.set_initial(opti.lam_g, sol.value(opti.lam_g))
        return self._collect(value, stats, ok, iterations, time.perf_counter() - t0, solves)

    def _collect(self, value, stats, ok: bool, iterations: int, solve_time: float, rounds: int = 1) -> OcpSolution:
        pb, n = self.pb, self.n
        out_p, out_v, out_a, out_j = {}, {}, {}, {}
        for a in pb.agents:
            if a.moving:
                x = np.asarray(value(self.X[a.name])).reshape(9, n + 1)
                out_p[a.name], out_v[a.name], out_a[a.name] = x[0:3].T, x[3:6].T, x[6:9].T
                out_j[a.name] = np.asarray(value(self.U[a.name])).reshape(3, n).T
            else:
                out_p[a.name] = np.tile(np.asarray(a.start_m, float), (n + 1, 1))
                out_v[a.name] = np.zeros((n + 1, 3))
                out_a[a.name] = np.zeros((n + 1, 3))
                out_j[a.name] = np.zeros((n, 3))
        if self.phase_T:
            h_row = np.asarray(value(self.h_row), float).reshape(-1)
        else:
            assert pb.fixed_duration_s is not None
            h_row = np.full(n, pb.fixed_duration_s / n)
        try:  # largest violation of the (linearised) NLP's constraints at the returned point
            g = np.asarray(value(self.opti.g), float).reshape(-1)
            lbg = np.asarray(value(self.opti.lbg), float).reshape(-1)
            ubg = np.asarray(value(self.opti.ubg), float).reshape(-1)
            violation = float(np.max(np.concatenate([[0.0], lbg - g, g - ubg])))
        except (RuntimeError, ValueError):
            violation = float("nan")
        return OcpSolution(
            success=ok,
            status=str(stats.get("return_status", "unknown")),
            duration_s=float(np.sum(h_row)),
            node_times_s=np.concatenate([[0.0], np.cumsum(h_row)]),
            constraint_violation=violation,
            rounds=rounds,
            position_m=out_p,
            velocity_mps=out_v,
            acceleration_mps2=out_a,
            jerk_mps3=out_j,
            iterations=iterations,
            solve_time_s=solve_time,
            build_time_s=0.0,
            objective=float(value(self.cost)),
        )


def build_and_solve(
    problem: OcpProblem,
    *,
    progress: Callable[[str], None] | None = None,
    accept: Callable[[OcpSolution], bool] | None = None,
) -> OcpSolution:
    """Build the Opti problem, warm-start it and solve it with IPOPT (print_level 0).

    With the linearised table, ``accept(solution)`` is asked after each converged round; True stops
    the re-linearisation early (e.g. when the verifier already passes)."""
    t0 = time.perf_counter()
    problem, _ = repair_warm_start(problem)
    b = _Builder(problem)
    b.add_vehicles()
    b.add_pairs()
    b.add_authority()
    build_time = time.perf_counter() - t0
    sol = b.solve(progress, accept)
    return OcpSolution(**{**sol.__dict__, "build_time_s": build_time})


def sample_solution(
    solution: OcpSolution, times_s: np.ndarray, *, time_scale: float = 1.0
) -> dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Evaluate the piecewise-constant-jerk trajectories exactly at ``times_s`` (M,), s.

    ``time_scale`` >= 1 slows the whole solution uniformly (duration x s; v / s, a / s^2).
    Returns {name: (position_m (M, 3), velocity_mps (M, 3), acceleration_mps2 (M, 3))}.
    """
    nodes = solution.times_s()  # (n+1,) s
    n = nodes.size - 1
    tau = np.clip(np.asarray(times_s, float) / time_scale, 0.0, solution.duration_s)
    k = np.clip(np.searchsorted(nodes, tau, side="right") - 1, 0, n - 1)
    dt = (tau - nodes[k])[:, None]
    out = {}
    for name in solution.position_m:
        p0, v0 = solution.position_m[name][k], solution.velocity_mps[name][k]
        a0, j = solution.acceleration_mps2[name][k], solution.jerk_mps3[name][k]
        p = p0 + v0 * dt + a0 * dt**2 / 2 + j * dt**3 / 6
        v = (v0 + a0 * dt + j * dt**2 / 2) / time_scale
        a = (a0 + j * dt) / time_scale**2
        out[name] = (p, v, a)
    return out
