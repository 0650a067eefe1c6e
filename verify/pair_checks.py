"""The verifier's checks between vehicles (DESIGN.md s. 3; checks 4 and 5 of
:mod:`proxplan.verify.checks`): separation and invalid zone of every pair, authority usage with the
model's numbers, and authority usage with each target at the worst point of its tube (tracking tube
while the pair moves, plus the target's predicted deflection).

Pairs are evaluated on the (pair, sample) rows within the largest distance a check can fire at
(:func:`proxplan.verify.reach.pairs_within`), in batches per pair of vehicle types; the result is
what a loop over every pair gives (tests/verify/test_equivalence.py). World frame, z up; m, N, s.
"""

from __future__ import annotations

import numpy as np

from proxplan.physics import VALIDITY_FACTOR_L, invalid_zone_mask
from proxplan.planfile import Plan, Scenario
from proxplan.verify.along import Samples, WrenchAlongPlan, dock_exempt, moving_mask
from proxplan.verify.reach import NEGLIGIBLE_USAGE, counts_above, every_pair, pairs_within, usage_grid
from proxplan.verify.tolerances import USAGE_TOLERANCE
from proxplan.verify.violations import Violation, add_runs


def check_pairs(
    plan: Plan, scenario: Scenario, t: np.ndarray, samples: Samples, deflection: dict[str, np.ndarray]
) -> list[Violation]:
    """Separation and invalid zone of every pair, evaluated on the (pair, sample) rows horizontally
    within the largest distance either check can fire at (the separation with the tube, the
    footprints with the tube; :func:`proxplan.verify.reach.pairs_within`); violations in the order
    of a loop over pairs. The tube of a row is ``limits.tracking_margin_m`` while either vehicle
    moves plus both vehicles' predicted deflections (``deflection``: per vehicle (M,), m);
    ``samples``: the plan's :data:`proxplan.verify.along.Samples` on ``t``."""
    out: list[Violation] = []
    lim = scenario.limits
    names = list(plan.vehicles)
    pos = {n: samples[n][0] for n in names}
    if len(names) < 2:
        return out
    vehicles = [scenario.vehicles[n].vehicle for n in names]
    moving = moving_mask(plan, names, t, samples)
    p = np.stack([pos[n] for n in names])  # (N, M, 3)
    rb = np.array([v.body_radius_m for v in vehicles])
    sep0 = np.maximum(lim.min_separation_m, rb[:, None] + rb[None, :])  # (N, N), m
    defl = np.stack([deflection[n] for n in names])  # (N, M), m
    dm = defl.max(axis=1, initial=0.0)  # each vehicle's largest deflection, m
    ii, jj, mm = pairs_within(p[:, :, :2], sep0 + lim.tracking_margin_m + dm[:, None] + dm[None, :] + 1e-9)
    tube = np.where(moving[ii, mm] | moving[jj, mm], lim.tracking_margin_m, 0.0) + defl[ii, mm] + defl[jj, mm]  # m
    exempt = dock_rows(plan, scenario, names, pos, t, ii, jj, mm)
    d = np.linalg.norm(p[ii, mm] - p[jj, mm], axis=1)
    short = (d < sep0[ii, jj] + tube - 1e-6) & ~exempt
    kinds = list(dict.fromkeys(vehicles))
    kind = np.array([kinds.index(v) for v in vehicles])
    zone = []  # per direction (ii below jj, then jj below ii): (inside per row, depth per row (m))
    if lim.invalid_zone_rule != "model":
        for tg, sr in ((ii, jj), (jj, ii)):
            off = p[tg, mm] - p[sr, mm]
            hit = np.zeros(ii.size, dtype=bool)
            depth = np.zeros(ii.size)
            group = kind[sr] * len(kinds) + kind[tg]
            for g in np.unique(group):
                sel = group == g
                vs, vt = kinds[g // len(kinds)], kinds[g % len(kinds)]
                hit[sel] = invalid_zone_mask(vs, vt, off[sel], tube[sel])
                depth[sel] = VALIDITY_FACTOR_L * vs.size_m + tube[sel] + off[sel, 2]  # 3 L + tube - dz
            zone.append((hit & ~exempt, depth))
    bad = short.copy()
    for hit, _ in zone:
        bad |= hit
    order = np.lexsort((mm, ii * len(names) + jj))  # rows by pair, then sample
    key = (ii * len(names) + jj)[order]
    for k in np.unique(key[bad[order]]):
        a, b = int(k) // len(names), int(k) % len(names)
        rows = order[np.searchsorted(key, k, side="left") : np.searchsorted(key, k, side="right")]
        mask = np.zeros(t.size, dtype=bool)
        value = np.zeros(t.size)
        mask[mm[rows]], value[mm[rows]] = short[rows], sep0[a, b] + tube[rows] - d[rows]
        add_runs(
            out,
            t,
            mask,
            value,
            sep0[a, b] + lim.tracking_margin_m,
            names[a],
            "separation",
            f"closer than {sep0[a, b]:.3f} m + tracking tube {lim.tracking_margin_m:g} m (while moving) + predicted "
            f"deflections to {names[b]} by (m)",
            plan_t_s=plan.t_s,
        )
        for (tgt, src), (hit, depth) in zip(((a, b), (b, a)), zone):
            mask = np.zeros(t.size, dtype=bool)
            value = np.zeros(t.size)
            mask[mm[rows]], value[mm[rows]] = hit[rows], depth[rows]
            add_runs(
                out,
                t,
                mask,
                value,
                0.0,
                names[tgt],
                "invalid-zone",
                f"below {names[src]} inside its invalid zone grown by the tracking tube (dz <= 3 L + tube, "
                "footprints + tube overlap); depth (m)",
                plan_t_s=plan.t_s,
            )
    return out


def dock_rows(plan, scenario, names, pos, t, ii, jj, mm) -> np.ndarray:
    """(R,) True on the rows (vehicles ii and jj, either order, at sample mm) where a dock pair is on
    its approach."""
    out = np.zeros(ii.size, dtype=bool)
    index = {n: k for k, n in enumerate(names)}
    for name, task in scenario.vehicles.items():
        if task.dock_with is None or name not in index or task.dock_with not in index:
            continue
        a, b = index[name], index[task.dock_with]
        rows = ((ii == a) & (jj == b)) | ((ii == b) & (jj == a))
        if rows.any():
            out[rows] = dock_exempt(plan, scenario, names[a], names[b], pos, t)[mm[rows]]
    return out


def check_authority(scenario: Scenario, t: np.ndarray, along: dict[str, WrenchAlongPlan], plan_t_s) -> list[Violation]:
    out: list[Violation] = []
    limit = scenario.limits.authority_fraction
    for name, w in along.items():
        over = w.usage > limit + USAGE_TOLERANCE
        if over.any():
            worst_src = max(
                w.usage_by_source.items(),
                key=lambda kv: float(np.max(np.where(over, kv[1], 0.0))),
                default=(None, None),
            )[0]
            add_runs(
                out,
                t,
                over,
                w.usage,
                limit,
                name,
                "authority",
                f"authority usage in the downwash of {worst_src}",
                plan_t_s=plan_t_s,
            )
    return out


def tube_offsets(off: np.ndarray, tube_m: float | np.ndarray) -> list[np.ndarray]:
    """Offsets (N, 3) of a target within the tracking tube (m, one or (N,)) that the downwash hits
    hardest: moved horizontally towards the source's axis by the tube, at dz and dz +- tube (dz
    kept > 1 mm)."""
    r = np.hypot(off[:, 0], off[:, 1])
    shrink = np.where(r > 1e-9, np.maximum(r - tube_m, 0.0) / np.maximum(r, 1e-9), 0.0)
    base = off * np.column_stack([shrink, shrink, np.ones_like(shrink)])
    out = []
    for dz_shift in (-tube_m, 0.0, tube_m):
        o = base.copy()
        o[:, 2] = np.minimum(o[:, 2] - dz_shift, -1e-3)  # offset z = -dz; dz + shift, still below
        out.append(o)
    return out


def check_authority_tube(
    plan: Plan, scenario: Scenario, t: np.ndarray, samples: Samples, deflection: dict[str, np.ndarray]
) -> list[Violation]:
    """Authority usage with every moving (or deflected) pair's target placed, per source, at the
    worst point of its tube (``limits.tracking_margin_m`` while the pair moves, plus the target's
    predicted deflection, ``deflection``: per vehicle (M,), m; dock pairs on their approach exempt,
    as for the planner's cut-off): the verifier's form of the planner's grown cut-off radius.

    Evaluated on the (target, source, sample) rows within the pair's reach grown by the tube
    (:mod:`proxplan.verify.reach`), in batches per pair of vehicle types, and only where a bound
    of the usage (:meth:`proxplan.verify.reach.UsageGrid.bound` summed over the sources) exceeds
    the limit; whether a target has a moving pair at all (where the check applies) is counted
    exactly over every source above it. ``samples``: the plan's
    :data:`proxplan.verify.along.Samples` on ``t``."""
    from proxplan.physics import authority_usage, disturbance_wrench
    from proxplan.verify.along import model_options
    from proxplan.verify.plan_wrench import oriented_rows, plan_extent_m

    out: list[Violation] = []
    tube0 = scenario.limits.tracking_margin_m
    names = list(plan.vehicles)
    pos = {k: samples[k][0] for k in names}
    defl = np.stack([deflection[k] for k in names]) if names else np.zeros((0, t.size))  # (N, M), m
    if len(names) < 2 or (tube0 <= 0.0 and not (defl > 0.0).any()):
        return out
    limit = scenario.limits.authority_fraction
    opts = model_options(scenario)
    n, m = len(names), t.size
    vehicles = [scenario.vehicles[k].vehicle for k in names]
    kinds = list(dict.fromkeys(vehicles))
    kind = np.array([kinds.index(v) for v in vehicles])
    moving = moving_mask(plan, names, t, samples)
    if tube0 <= 0.0:
        moving = np.zeros_like(moving)  # no tracking tube: only the deflections widen a target's tube
    tube_max = max(tube0, 0.0) + float(defl.max(initial=0.0))  # the widest tube of any row, m
    p = np.stack([pos[k] for k in names])  # (N, M, 3)
    dz_max, r_max = plan_extent_m(p)
    grids = [  # [source kind][target kind]: the plain model's usage bound down to the widest tube deeper
        [usage_grid(s, g, opts, (), dz_lo_m=0.0, dz_hi_m=dz_max + tube_max, r_max_m=r_max) for g in kinds]
        for s in kinds
    ]
    reach = np.array([[grid.reach_m for grid in row] for row in grids])
    radius = (
        np.full((n, n), np.inf)
        if every_pair(n, m)
        else np.maximum(reach[kind][:, kind], reach[kind][:, kind].T)
        + max(tube0, 0.0)
        + np.maximum.outer(defl.max(axis=1, initial=0.0), defl.max(axis=1, initial=0.0))
    )
    ii, jj, mm = pairs_within(p[:, :, :2], radius + 1e-9)
    tgt, src, smp, off = oriented_rows(p, ii, jj, mm, both=False)
    below = -off[:, 2] > 1e-6
    tgt, src, smp, off = tgt[below], src[below], smp[below], off[below]
    tube = np.where(moving[tgt, smp] | moving[src, smp], max(tube0, 0.0), 0.0) + defl[tgt, smp]  # per row, m
    tubed = has_tubed_pair(plan, scenario, names, pos, t, p[:, :, 2], moving, defl > 0.0)
    # screen: a bound of each row's usage (the plain offset and every tube offset), summed per
    # (target, sample); where the sum stays within the limit the check cannot fire (usage is
    # subadditive), so only the other (target, sample) rows are evaluated
    dz, hor = -off[:, 2], np.hypot(off[:, 0], off[:, 1])
    bound = np.zeros(tgt.size)
    group = kind[src] * len(kinds) + kind[tgt]
    for g in np.unique(group):
        sel = group == g
        bound[sel] = grids[g // len(kinds)][g % len(kinds)].bound(
            np.maximum(hor[sel] - tube[sel], 0.0),
            np.minimum(dz[sel], np.maximum(dz[sel] - tube[sel], 1e-3)),
            np.maximum(dz[sel] + tube[sel], 1e-3),
        )
    worst = np.full((n, m), (n - 1) * NEGLIGIBLE_USAGE)  # sources beyond the reach
    np.add.at(worst, (tgt, smp), bound)
    maybe = tubed & (worst > limit + USAGE_TOLERANCE)
    keep = maybe[tgt, smp] & (every_pair(n, m) | (bound >= NEGLIGIBLE_USAGE))  # rows that can count
    tgt, src, smp, off, group, tube = tgt[keep], src[keep], smp[keep], off[keep], group[keep], tube[keep]
    use = (tube > 0.0) & ~dock_rows(plan, scenario, names, pos, t, tgt, src, smp)
    force = np.zeros((n, m, 3))
    torque = np.zeros((n, m, 3))
    for g in np.unique(group):
        source, target = kinds[g // len(kinds)], kinds[g % len(kinds)]
        plain = np.flatnonzero((group == g) & ~use)
        if plain.size:
            w = disturbance_wrench(source, target, off[plain], opts)
            np.add.at(force, (tgt[plain], smp[plain]), w.force_N)
            np.add.at(torque, (tgt[plain], smp[plain]), w.torque_Nm)
        tubed_rows = np.flatnonzero((group == g) & use)
        if tubed_rows.size:
            best_u = np.full(tubed_rows.size, -np.inf)
            best_f = np.zeros((tubed_rows.size, 3))
            best_t = np.zeros((tubed_rows.size, 3))
            for o in tube_offsets(off[tubed_rows], tube[tubed_rows]):
                w = disturbance_wrench(source, target, o, opts)
                u = authority_usage(target, w.force_N, w.torque_Nm)
                better = u > best_u
                best_u[better], best_f[better], best_t[better] = u[better], w.force_N[better], w.torque_Nm[better]
            np.add.at(force, (tgt[tubed_rows], smp[tubed_rows]), best_f)
            np.add.at(torque, (tgt[tubed_rows], smp[tubed_rows]), best_t)
    for k, tname in enumerate(names):
        usage = authority_usage(vehicles[k], force[k], torque[k])
        over = maybe[k] & (usage > limit + USAGE_TOLERANCE)
        add_runs(
            out,
            t,
            over,
            usage,
            limit,
            tname,
            "authority-tube",
            f"authority usage within the tracking tube ({tube0:g} m, + predicted deflection) of the plan",
            plan_t_s=plan.t_s,
        )
    return out


def has_tubed_pair(
    plan, scenario, names, pos, t, z_m: np.ndarray, moving: np.ndarray, deflected: np.ndarray
) -> np.ndarray:
    """(N, M) True where a vehicle has a source above it (by more than 1e-6 m) with either of the
    two moving, or the vehicle itself ``deflected`` (its tube is wider than zero), the pair not a
    dock pair on its approach: counted over every vehicle."""
    n_above = counts_above(z_m)
    n_moving_above = counts_above(z_m, moving)
    index = {k: i for i, k in enumerate(names)}
    for name, task in scenario.vehicles.items():
        if task.dock_with is None or name not in index or task.dock_with not in index:
            continue
        ex = dock_exempt(plan, scenario, name, task.dock_with, pos, t)
        for a, b in ((index[name], index[task.dock_with]), (index[task.dock_with], index[name])):
            gone = ex & (z_m[b] - z_m[a] > 1e-6)  # b above a, exempt: not a pair for the tube
            n_above[a] -= gone
            n_moving_above[a] -= gone & moving[b]
    return ((moving | deflected) & (n_above > 0)) | (n_moving_above > 0)
