"""Authority usage <= ``authority_fraction`` at the check points of the Opti problem
(:class:`proxplan.planner.optimizer.ocp_builder.OcpBuilder`): the disturbance wrench on each
target from the wrench table of each other vehicle (or its linearisation), mapped through the
inverse mixer of (S0-14) to per-motor thrust changes bounded by ``fraction x headroom``; the dock
pairs' approach envelope; and the exposure term of the objective."""

from __future__ import annotations

from typing import Any

import numpy as np

from proxplan.physics import normalised_motor_map
from proxplan.planner.optimizer.ocp_builder import OcpBuilder


def add_authority(b: OcpBuilder) -> None:
    """Authority usage <= fraction at the check points. All offsets that share one wrench
    function (one vehicle-type pair) go through a single ``Function.map`` call; sparse
    selection matrices scatter the per-motor changes to (target, check point)."""
    ca, opti, pb, n = b.ca, b.opti, b.pb, b.n
    nq = 2 * n + 1
    # quadrature weights of the check points (nodes, then midpoints), s: node k gets a quarter of
    # each adjacent interval, a midpoint half of its own, so the exposure is a time integral
    # (a longer stay in a jet costs more; with one weight per check point instead, the two-phase
    # docking problem preferred to stretch its approach phase)
    h_row = b.h_row
    zero = ca.DM.zeros(1, 1)
    node_w = 0.25 * (ca.horzcat(zero, h_row) + ca.horzcat(h_row, zero))
    quad_w = ca.horzcat(node_w, 0.5 * h_row)  # (1, nq) s
    groups: dict[int, dict] = {}  # id(fn) -> {"fn", "offsets": [MX], "rows": [(target, ks)]}
    for nt in b.names:
        for ns in b.names:
            fn = pb.wrench_functions.get((ns, nt))
            if ns == nt or fn is None or not (b.agents[ns].moving or b.agents[nt].moving):
                continue
            rel_w = b.Qw[nt] - b.Qw[ns]
            r_w = np.hypot(rel_w[:, 0], rel_w[:, 1])
            near = (r_w <= pb.interaction_radius_m) & (rel_w[:, 2] < 0.5)
            extent = pb.interaction_extent.get((ns, nt))
            if extent is not None:
                dz_w = np.maximum(-rel_w[:, 2], 0.0)
                near &= (r_w <= np.asarray(extent(dz_w)) + pb.extent_margin_m) & (rel_w[:, 2] < pb.extent_margin_m)
            if (ns, nt) in pb.dock_usage_functions:  # the approach: the model's envelope instead
                near &= ~b.is_exempt(ns, nt)
            ks = np.flatnonzero(near)
            if ks.size == 0:
                continue
            g = groups.setdefault(id(fn), {"fn": fn, "offsets": [], "rows": []})
            rel = b.Q[nt][:, ks.tolist()] - b.Q[ns][:, ks.tolist()]
            tube = pb.tube_m * (b.may_move(b.agents[ns]) | b.may_move(b.agents[nt]))[ks]
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
    b.linear_groups = []
    for g in groups.values():
        offsets = ca.horzcat(*g["offsets"])
        m_all = int(offsets.shape[1])
        if pb.linearize:
            # first-order model of the table about parameters O0: W0 + J (O - O0), re-linearised
            # by build_and_solve between solves (keeps the NLP SX-expandable)
            o0, w0, jac = opti.parameter(3, m_all), opti.parameter(3, m_all), opti.parameter(9, m_all)
            d = offsets - o0
            w = ca.vertcat(*[w0[i, :] + ca.sum1(jac[3 * i : 3 * i + 3, :] * d) for i in range(3)])
            b.linear_groups.append({"fn": g["fn"], "offsets": offsets, "o0": o0, "w0": w0, "jac": jac})
            b.cost += pb.proximal_weight * ca.sumsqr(d)
        else:
            w = g["fn"].map(m_all)(offsets)  # (3, M): F_z N, tau_x N m, tau_y N m
        col = 0
        for nt, ks in g["rows"]:
            m = int(ks.size)
            a_map, up, down = normalised_motor_map(b.agents[nt].vehicle)
            per_source = ca.mtimes(ca.DM(a_map), w[:, col : col + m])  # (4, m) motor changes, N
            # exposure per (source, target) pair: sum_k w_k |delta_f / headroom|^2 (pairwise
            # terms keep the Hessian sparse; the constraint below uses the sum over sources)
            scaled = per_source * ca.DM(np.outer(1.0 / np.minimum(up, down), np.ones(m)))
            b.cost += pb.weights.exposure * ca.dot(ca.sum1(scaled**2), quad_w[:, ks.tolist()])
            select = ca.DM.triplet(list(range(m)), ks.tolist(), ca.DM.ones(m), m, nq)
            contrib = ca.mtimes(per_source, select)  # (4, nq) N
            totals[nt] = contrib if nt not in totals else totals[nt] + contrib
            active.setdefault(nt, np.zeros(nq, dtype=bool))[ks] = True
            col += m
    approach = approach_usage(b, quad_w)  # target -> (columns, usage envelope (1, m))
    for nt in approach:
        if nt not in totals:  # the dock partner is the only source: bound its envelope alone
            cols, env = approach[nt]
            opti.subject_to(env <= pb.authority_fraction - 2e-4)
    for nt, total in totals.items():
        a_map, up, down = normalised_motor_map(b.agents[nt].vehicle)
        frac = np.full(nq, pb.authority_fraction * pb.authority_margin)
        frac[n] = pb.authority_fraction - 2e-4  # the final state is static: full fraction
        bg = b.agents[nt].background_wrench
        if bg is not None:  # sources outside the problem (fixed): a constant motor-thrust change, N
            bg_motor = a_map @ np.asarray(bg, float).reshape(3, nq)
            total = total + ca.DM(bg_motor)
            # where the background alone already uses the margin, allow what it uses (+0.01):
            # the optimised vehicle then may add little there; the verifier has the last word
            bg_usage = np.maximum((bg_motor / up[:, None]).max(axis=0), (-bg_motor / down[:, None]).max(axis=0))
            frac = np.maximum(frac, np.minimum(bg_usage + 0.01, pb.authority_fraction - 2e-4))
        for key, ex in b.exempt.items():
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


def approach_usage(b: OcpBuilder, quad_w) -> dict[str, tuple[list[int], Any]]:
    """Dock pairs on their final approach (exempt check points): the target's authority usage
    from its dock partner is the model's envelope ``dock_usage_functions[(source, target)](dz)``
    (the extrapolated near field inside the invalid zone, as the verifier checks it) instead of
    the wrench table, which holds its first layer there. Adds the exposure of those points
    (4 motors x usage^2, the table's measure for a vertical force) and returns, per target,
    the check-point columns and the envelope values (1, m)."""
    ca, pb = b.ca, b.pb
    out: dict[str, tuple[list[int], Any]] = {}
    for (ns, nt), fn in pb.dock_usage_functions.items():
        if ns not in b.agents or nt not in b.agents:
            continue
        ks = np.flatnonzero(b.is_exempt(ns, nt)).tolist()
        if not ks:
            continue
        dz = b.Q[ns][2, ks] - b.Q[nt][2, ks]  # (1, m) m, target below the source
        env = fn.map(len(ks))(dz)
        b.cost += pb.weights.exposure * ca.dot(4.0 * env**2, quad_w[:, ks])
        out[nt] = (ks, env)
    return out
