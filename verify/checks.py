"""Independent plan verifier: trusts nothing in the plan, re-samples it finely and evaluates the
disturbance model directly (not the cost maps, not the planner's checker).

Checks, in this order (a plan that fails the first group is not checked further):

1. *Vehicles*: every scenario vehicle has a trajectory and no other is present; each flies the type
   and parameters its task names; the plan starts at t = 0 at the scenario's start positions.
2. *What will fly is self-consistent* (on the plan grid, step h): positions, velocities and
   accelerations agree with each other, p[k+1] - p[k] = h (v[k] + v[k+1]) / 2 + h^2 (a[k] - a[k+1]) / 12
   (exact for cubics) within ``POSITION_CONSISTENCY_M`` + J h^3 / 4 and
   v[k+1] - v[k] = h (a[k] + a[k+1]) / 2 within ``VELOCITY_CONSISTENCY_MPS`` + J h^2 / 2 (J: the
   vehicle's jerk limit, bounding what a jerk switch inside a step may add); speed, acceleration and
   jerk (finite differences of the acceleration) within the vehicle's limits, and the speed implied
   by the positions alone (|dp| / h) too.
3. *Task*: workspace (body disc inside), obstacles (body disc outside every box), goals / hover /
   docks reached and at rest at the end.
4. *Pairs*: separation (centre distance >= max(limits.min_separation_m, sum of body radii); dock
   pairs exempt on their final approach), the invalid zone (0 < dz <= 3 L of a source with
   overlapping footprints, forbidden for non-dock pairs unless ``invalid_zone_rule: model``).
   While either vehicle of a pair moves (plan speed >= ``REST_SPEED_MPS``) both checks add the
   tracking tube ``limits.tracking_margin_m`` t: separation + t, dz <= 3 L + t, footprints + t
   (a vehicle flown closed-loop may be that far off its plan; a resting one is not). Where the
   model predicts a disturbance on a vehicle, its predicted deflection d (``deflection_along_plan``:
   the sag F / k_p and its transient under the plan's own predicted wrench) is part of its tube,
   moving or not: the pair's tube is t + d_a + d_b.
5. *Authority*: usage <= limits.authority_fraction with the model's numbers everywhere (also where
   it is extrapolated); and, while a pair moves, also with the target at the worst point of the
   tracking tube (plus the target's predicted deflection) for each source (towards the source's
   axis by the tube, at dz and dz +- tube; dock pairs exempt on their approach as from the
   planner's cut-off).

Consecutive violating samples of one kind merge into one :class:`Violation` that names the vehicle,
the plan sample and time where it starts, the check, and its worst value against the limit.
"""

from __future__ import annotations

import numpy as np

from proxplan.fileio import UserError
from proxplan.physics import VALIDITY_FACTOR_L, invalid_zone_mask
from proxplan.planfile import Plan, Scenario, load_scenario, scenario_from_dict
from proxplan.verify.along import WrenchAlongPlan, deflection_along_plan, dock_exempt, wrench_along_plan
from proxplan.verify.reach import NEGLIGIBLE_USAGE, counts_above, every_pair, pairs_within, usage_grid
from proxplan.verify.violations import Violation, add_runs

GOAL_TOLERANCE_M = 0.05  # goal, hover, dock and start positions, m
USAGE_TOLERANCE = 1e-3  # authority usage, -
KINEMATIC_TOLERANCE = 1.02  # 2 % on speed / acceleration; jerk from finite differences gets 10 %
JERK_TOLERANCE = 1.1
POSITION_CONSISTENCY_M = 2e-3  # position vs integrated velocity/acceleration per step, m
VELOCITY_CONSISTENCY_MPS = 5e-3  # velocity vs integrated acceleration per step, m/s
REST_SPEED_MPS = 0.05  # "at rest" (end of the plan; no tracking tube while both of a pair rest), m/s


def _check_vehicles(plan: Plan, scenario: Scenario) -> list[Violation]:
    out: list[Violation] = []
    for n in scenario.vehicles:
        if n not in plan.vehicles:
            out.append(
                Violation(0.0, n, "missing", "vehicle of the scenario has no trajectory in the plan", 1.0, 0.0, 0)
            )
    for n in plan.vehicles:
        if n not in scenario.vehicles:
            out.append(Violation(0.0, n, "unknown", "vehicle is not in the scenario", 1.0, 0.0, 0))
    for n, tr in plan.vehicles.items():
        task = scenario.vehicles.get(n)
        if task is None:
            continue
        if tr.type_name != task.type_name or tr.vehicle != task.vehicle:
            out.append(
                Violation(
                    0.0,
                    n,
                    "vehicle-type",
                    f"flies type {tr.type_name!r}, the scenario's task names {task.type_name!r} (or other parameters)",
                    1.0,
                    0.0,
                    0,
                )
            )
    if abs(float(plan.t_s[0])) > 1e-6:
        first = next(iter(plan.vehicles))
        out.append(
            Violation(
                float(plan.t_s[0]),
                first,
                "time-grid",
                "plan does not start at t = 0 (s)",
                abs(float(plan.t_s[0])),
                0.0,
                0,
            )
        )
    return out


def _check_consistency(plan: Plan, scenario: Scenario) -> list[Violation]:
    """Positions, velocities and accelerations agree with each other and with the limits."""
    out: list[Violation] = []
    for name, tr in plan.vehicles.items():
        task = scenario.vehicles[name]
        t, p, v, a = tr.t_s, tr.position_m, tr.velocity_mps, tr.acceleration_mps2
        h = np.diff(t)[:, None]
        jerk_max = task.max_jerk_mps3 * JERK_TOLERANCE
        p_pred = h * (v[:-1] + v[1:]) / 2 + h**2 * (a[:-1] - a[1:]) / 12
        p_err = np.linalg.norm(p[1:] - p[:-1] - p_pred, axis=1)
        p_tol = POSITION_CONSISTENCY_M + jerk_max * h[:, 0] ** 3 / 4
        add_runs(
            out,
            t[:-1],
            p_err > p_tol,
            p_err,
            float(p_tol.max()),
            name,
            "consistency",
            "position step disagrees with the velocities and accelerations by (m)",
            plan_t_s=t,
        )
        v_err = np.linalg.norm(v[1:] - v[:-1] - h * (a[:-1] + a[1:]) / 2, axis=1)
        v_tol = VELOCITY_CONSISTENCY_MPS + jerk_max * h[:, 0] ** 2 / 2
        add_runs(
            out,
            t[:-1],
            v_err > v_tol,
            v_err,
            float(v_tol.max()),
            name,
            "consistency",
            "velocity step disagrees with the accelerations by (m/s)",
            plan_t_s=t,
        )
        step_speed = np.linalg.norm(np.diff(p, axis=0), axis=1) / h[:, 0]
        v_lim = task.max_speed_mps * KINEMATIC_TOLERANCE + 1e-3
        add_runs(
            out,
            t[:-1],
            step_speed > v_lim,
            step_speed,
            task.max_speed_mps,
            name,
            "speed",
            "speed implied by consecutive positions (m/s)",
            plan_t_s=t,
        )
        speed = np.linalg.norm(v, axis=1)
        add_runs(out, t, speed > v_lim, speed, task.max_speed_mps, name, "speed", "speed (m/s)", plan_t_s=t)
        acc = np.linalg.norm(a, axis=1)
        a_lim = task.max_accel_mps2 * KINEMATIC_TOLERANCE + 1e-3
        add_runs(
            out, t, acc > a_lim, acc, task.max_accel_mps2, name, "acceleration", "acceleration (m/s^2)", plan_t_s=t
        )
        jerk = np.linalg.norm(np.diff(a, axis=0), axis=1) / h[:, 0]
        add_runs(
            out,
            t[1:],
            jerk > jerk_max + 1e-3,
            jerk,
            task.max_jerk_mps3,
            name,
            "jerk",
            "jerk from finite differences (m/s^3)",
            plan_t_s=t,
        )
        start_err = float(np.linalg.norm(p[0] - task.start_m))
        if start_err > GOAL_TOLERANCE_M:
            out.append(
                Violation(
                    float(t[0]),
                    name,
                    "start",
                    f"starts at {np.round(p[0], 3).tolist()}, the scenario says {task.start_m.tolist()} (m)",
                    start_err,
                    GOAL_TOLERANCE_M,
                    0,
                )
            )
    return out


def _check_tasks(plan: Plan, scenario: Scenario, t: np.ndarray, pos: dict[str, np.ndarray]) -> list[Violation]:
    out: list[Violation] = []
    lo, hi = scenario.workspace_min_m, scenario.workspace_max_m
    end = float(t[-1])
    last = plan.t_s.size - 1
    for name, tr in plan.vehicles.items():
        task = scenario.vehicles[name]
        p = pos[name]
        rb = task.vehicle.body_radius_m
        # workspace: the body disc inside the box horizontally, the centre inside vertically
        below_lo = np.max(np.column_stack([lo[0] + rb - p[:, 0], lo[1] + rb - p[:, 1], lo[2] - p[:, 2]]), axis=1)
        above_hi = np.max(np.column_stack([p[:, 0] + rb - hi[0], p[:, 1] + rb - hi[1], p[:, 2] - hi[2]]), axis=1)
        excess = np.maximum(below_lo, above_hi)
        add_runs(
            out, t, excess > 1e-6, excess, 0.0, name, "workspace", "body leaves the workspace by (m)", plan_t_s=plan.t_s
        )
        for i, box in enumerate(scenario.obstacles):
            gap_xy = np.hypot(
                np.maximum(0, np.maximum(box.min_m[0] - p[:, 0], p[:, 0] - box.max_m[0])),
                np.maximum(0, np.maximum(box.min_m[1] - p[:, 1], p[:, 1] - box.max_m[1])),
            )
            inside_z = (p[:, 2] >= box.min_m[2]) & (p[:, 2] <= box.max_m[2])
            pen = rb - gap_xy
            add_runs(
                out,
                t,
                inside_z & (pen > 1e-6),
                pen,
                0.0,
                name,
                "obstacle",
                f"body overlaps obstacles[{i}] by (m)",
                plan_t_s=plan.t_s,
            )
        final = p[-1]
        if task.goal_m is not None:
            err = float(np.linalg.norm(final - task.goal_m))
            if err > GOAL_TOLERANCE_M:
                out.append(
                    Violation(
                        end,
                        name,
                        "goal",
                        f"ends at {np.round(final, 3).tolist()}, goal {task.goal_m.tolist()}",
                        err,
                        GOAL_TOLERANCE_M,
                        last,
                    )
                )
        elif task.hover:
            err_t = np.linalg.norm(p - task.start_m, axis=1)
            add_runs(
                out,
                t,
                err_t > GOAL_TOLERANCE_M,
                err_t,
                GOAL_TOLERANCE_M,
                name,
                "hover",
                "drifts from its hover point (m)",
                plan_t_s=plan.t_s,
            )
        else:
            assert task.dock_with is not None and task.dock_offset_m is not None
            want = pos[task.dock_with][-1] + task.dock_offset_m
            err = float(np.linalg.norm(final - want))
            if err > GOAL_TOLERANCE_M:
                out.append(
                    Violation(
                        end,
                        name,
                        "dock",
                        f"ends {err:.3f} m from {task.dock_with} + offset {task.dock_offset_m.tolist()}",
                        err,
                        GOAL_TOLERANCE_M,
                        last,
                    )
                )
        speed_end = float(np.linalg.norm(tr.velocity_mps[-1]))
        if speed_end > REST_SPEED_MPS:
            out.append(
                Violation(
                    end,
                    name,
                    "not-at-rest",
                    "still moving at the end of the plan (m/s)",
                    speed_end,
                    REST_SPEED_MPS,
                    last,
                )
            )
    return out


def _check_pairs(
    plan: Plan, scenario: Scenario, t: np.ndarray, pos: dict[str, np.ndarray], deflection: dict[str, np.ndarray]
) -> list[Violation]:
    """Separation and invalid zone of every pair, evaluated on the (pair, sample) rows horizontally
    within the largest distance either check can fire at (the separation with the tube, the
    footprints with the tube; :func:`proxplan.verify.reach.pairs_within`); violations in the order
    of a loop over pairs. The tube of a row is ``limits.tracking_margin_m`` while either vehicle
    moves plus both vehicles' predicted deflections (``deflection``: per vehicle (M,), m)."""
    out: list[Violation] = []
    lim = scenario.limits
    names = list(plan.vehicles)
    if len(names) < 2:
        return out
    vehicles = [scenario.vehicles[n].vehicle for n in names]
    moving = np.stack([np.linalg.norm(plan.vehicles[n].sample(t)[1], axis=1) >= REST_SPEED_MPS for n in names])
    p = np.stack([pos[n] for n in names])  # (N, M, 3)
    rb = np.array([v.body_radius_m for v in vehicles])
    sep0 = np.maximum(lim.min_separation_m, rb[:, None] + rb[None, :])  # (N, N), m
    defl = np.stack([deflection[n] for n in names])  # (N, M), m
    ii, jj, mm = pairs_within(p[:, :, :2], sep0 + lim.tracking_margin_m + 2.0 * float(defl.max(initial=0.0)) + 1e-9)
    tube = np.where(moving[ii, mm] | moving[jj, mm], lim.tracking_margin_m, 0.0) + defl[ii, mm] + defl[jj, mm]  # m
    exempt = _dock_rows(plan, scenario, names, pos, t, ii, jj, mm)
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


def _dock_rows(plan, scenario, names, pos, t, ii, jj, mm) -> np.ndarray:
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


def _check_authority(scenario: Scenario, t: np.ndarray, along: dict[str, WrenchAlongPlan], plan_t_s) -> list[Violation]:
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


def _check_authority_tube(
    plan: Plan, scenario: Scenario, t: np.ndarray, pos: dict[str, np.ndarray], deflection: dict[str, np.ndarray]
) -> list[Violation]:
    """Authority usage with every moving (or deflected) pair's target placed, per source, at the
    worst point of its tube (``limits.tracking_margin_m`` while the pair moves, plus the target's
    predicted deflection, ``deflection``: per vehicle (M,), m; dock pairs on their approach exempt,
    as for the planner's cut-off): the verifier's form of the planner's grown cut-off radius.

    Evaluated on the (target, source, sample) rows within the pair's reach grown by the tube
    (:mod:`proxplan.verify.reach`), in batches per pair of vehicle types, and only where a bound
    of the usage (:meth:`proxplan.verify.reach.UsageGrid.bound` summed over the sources) exceeds
    the limit; whether a target has a moving pair at all (where the check applies) is counted
    exactly over every source above it."""
    from proxplan.physics import authority_usage, disturbance_wrench
    from proxplan.verify.along import model_options
    from proxplan.verify.plan_wrench import oriented_rows, plan_extent_m

    out: list[Violation] = []
    tube0 = scenario.limits.tracking_margin_m
    names = list(plan.vehicles)
    defl = np.stack([deflection[k] for k in names]) if names else np.zeros((0, t.size))  # (N, M), m
    if len(names) < 2 or (tube0 <= 0.0 and not (defl > 0.0).any()):
        return out
    limit = scenario.limits.authority_fraction
    opts = model_options(scenario)
    n, m = len(names), t.size
    vehicles = [scenario.vehicles[k].vehicle for k in names]
    kinds = list(dict.fromkeys(vehicles))
    kind = np.array([kinds.index(v) for v in vehicles])
    moving = np.stack([np.linalg.norm(plan.vehicles[k].sample(t)[1], axis=1) >= REST_SPEED_MPS for k in names])
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
        else np.maximum(reach[kind][:, kind], reach[kind][:, kind].T) + tube_max
    )
    ii, jj, mm = pairs_within(p[:, :, :2], radius + 1e-9)
    tgt, src, smp, off = oriented_rows(p, ii, jj, mm, both=False)
    below = -off[:, 2] > 1e-6
    tgt, src, smp, off = tgt[below], src[below], smp[below], off[below]
    tube = np.where(moving[tgt, smp] | moving[src, smp], max(tube0, 0.0), 0.0) + defl[tgt, smp]  # per row, m
    tubed = _has_tubed_pair(plan, scenario, names, pos, t, p[:, :, 2], moving, defl > 0.0)
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
    use = (tube > 0.0) & ~_dock_rows(plan, scenario, names, pos, t, tgt, src, smp)
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


def _has_tubed_pair(
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


def verify_plan(plan: Plan, scenario: Scenario, *, dt_fine_s: float = 0.01) -> list[Violation]:
    """Every violation of ``plan`` against ``scenario`` (empty list = the plan passes), sorted by
    time; the model checks run on a grid of step ``dt_fine_s``, s."""
    out = _check_vehicles(plan, scenario)
    if out:
        return out
    out = _check_consistency(plan, scenario)
    t = np.arange(0.0, float(plan.t_s[-1]) + dt_fine_s / 2, dt_fine_s)
    pos = plan.positions_at(t)
    out += _check_tasks(plan, scenario, t, pos)
    along = wrench_along_plan(plan, scenario, t_s=t)
    deflection = deflection_along_plan(plan, scenario, along)
    out += _check_pairs(plan, scenario, t, pos, deflection)
    out += _check_authority(scenario, t, along, plan.t_s)
    if not any(v.kind == "authority" for v in out):  # the plain check names the cause first
        out += _check_authority_tube(plan, scenario, t, pos, deflection)
    out.sort(key=lambda v: (v.t_s, v.vehicle, v.kind))
    return out


def scenario_of_plan(plan: Plan, *, label: str = "plan.json") -> Scenario:
    """The scenario a plan was made for: its embedded copy (with the plan's own vehicle types),
    else its scenario file."""
    if plan.scenario_spec is not None and plan.format_version >= 2:
        return scenario_from_dict(plan.scenario_spec, vehicle_types=plan.vehicle_types, label=f"{label}: scenario_spec")
    if plan.scenario_spec is not None:
        return scenario_from_dict(plan.scenario_spec, source_path=plan.scenario_file or None)
    if plan.scenario_file:
        return load_scenario(plan.scenario_file)
    raise UserError(f"{label}: scenario_spec / scenario_file: missing; pass the scenario with --scenario FILE.yaml")
