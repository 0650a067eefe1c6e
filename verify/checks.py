"""Independent plan verifier: re-samples a plan finely and evaluates the disturbance model directly.

It does not use the cost maps or the planner's checker: the wrench on each vehicle is the sum over
every other vehicle above it of ``physics.disturbance.disturbance_wrench`` (S0-3..S0-8), and its
authority usage comes from ``physics.authority.authority_usage`` (DESIGN.md s. 3). Positions
between plan samples come from the plan-file sampler (``planfile.plan.VehicleTrajectory.sample``).

Checks: workspace (body disc inside), obstacles (body disc outside every box), separation
(centre distance >= max(limits.min_separation_m, sum of body radii); dock pairs exempt on their
final approach), authority usage <= limits.authority_fraction (model numbers everywhere, also
where the model is extrapolated), the invalid zone (0 < dz <= 3 L of a source with overlapping
footprints, forbidden for non-dock pairs unless ``invalid_zone_rule: model``), goals / hover / docks
reached, speed, acceleration and jerk limits. Consecutive violating samples of the same kind merge
into one :class:`Violation` (its ``t_s`` is where it starts, ``value`` the worst value).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from physics.disturbance import VALIDITY_FACTOR_L, ModelOptions, disturbance_wrench
from physics.authority import authority_usage
from planfile.plan import Plan
from planfile.scenario import Scenario

GOAL_TOLERANCE_M = 0.05
DOCK_TUBE_M = 0.1  # radius of the dock-approach tube where a dock pair is exempt, m
USAGE_TOLERANCE = 1e-3
KINEMATIC_TOLERANCE = 1.02  # 2 % on speed / acceleration; jerk from finite differences gets 10 %


@dataclass(frozen=True)
class Violation:
    """One violated check: from ``t_s`` (s) on, ``vehicle`` broke ``kind`` (worst ``value`` vs ``limit``)."""

    t_s: float
    vehicle: str
    kind: str
    detail: str
    value: float
    limit: float

    def __str__(self) -> str:
        return f"t={self.t_s:.2f}s {self.vehicle}: {self.kind}: {self.detail} ({self.value:.4g} > limit {self.limit:.4g})"


@dataclass(frozen=True)
class WrenchAlongPlan:
    """Disturbance on one vehicle along the plan at times ``t_s`` (M,), s.

    ``force_N`` (M, 3) N and ``torque_Nm`` (M, 3) N m, world frame, summed over all sources above;
    ``usage`` (M,) authority usage; ``usage_by_source`` {source: (M,)} usage of each source alone;
    ``invalid_zone`` (M,) True where the vehicle is in a source's invalid zone (0 < dz <= 3 L) with
    overlapping footprints.
    """

    t_s: np.ndarray
    force_N: np.ndarray
    torque_Nm: np.ndarray
    usage: np.ndarray
    usage_by_source: dict
    invalid_zone: np.ndarray


def _options(scenario: Scenario) -> ModelOptions:
    return ModelOptions(field_form=scenario.field_form) if scenario.field_form else ModelOptions()


def wrench_along_plan(plan: Plan, scenario: Scenario, *, t_s: np.ndarray) -> dict[str, WrenchAlongPlan]:
    """Per-vehicle disturbance wrench and authority usage at times ``t_s`` (M,), s, summed over
    every other vehicle as a source (those above it), evaluated with the model directly."""
    t_s = np.asarray(t_s, dtype=float)
    pos = plan.positions_at(t_s)
    opts = _options(scenario)
    out = {}
    for tname in plan.vehicles:
        target = scenario.vehicles[tname].vehicle
        force = np.zeros((t_s.size, 3))
        torque = np.zeros((t_s.size, 3))
        by_source = {}
        invalid = np.zeros(t_s.size, dtype=bool)
        for sname in plan.vehicles:
            if sname == tname:
                continue
            source = scenario.vehicles[sname].vehicle
            off = pos[tname] - pos[sname]
            below = -off[:, 2] > 1e-6
            u_src = np.zeros(t_s.size)
            if below.any():
                w = disturbance_wrench(source, target, off[below], opts)
                force[below] += w.force_N
                torque[below] += w.torque_Nm
                u_src[below] = authority_usage(target, w.force_N, w.torque_Nm)
                r = np.hypot(off[below, 0], off[below, 1])
                inv = (-off[below, 2] <= VALIDITY_FACTOR_L * source.size_m) & (r < source.body_radius_m + target.body_radius_m)
                invalid[np.nonzero(below)[0][inv]] = True
            by_source[sname] = u_src
        usage = authority_usage(target, force, torque) if t_s.size else np.zeros(0)
        out[tname] = WrenchAlongPlan(t_s, force, torque, usage, by_source, invalid)
    return out


def _dock_exempt(plan: Plan, scenario: Scenario, a: str, b: str, pos: dict, t_s: np.ndarray) -> np.ndarray:
    """(M,) True where pair (a, b) is a dock pair and the docker is on its final approach: within
    ``DOCK_TUBE_M`` of the segment from the approach point A to the dock point D, both taken
    relative to the dock target's current position."""
    for docker, target in ((a, b), (b, a)):
        task = scenario.vehicles[docker]
        if task.dock_with == target:
            ap, dp = scenario.dock_geometry(docker)
            base = scenario.final_position_m(target)
            a_rel, d_rel = ap - base, dp - base  # relative to the target
            rel = pos[docker] - pos[target]
            seg = a_rel - d_rel
            f = np.clip((rel - d_rel) @ seg / max(float(seg @ seg), 1e-12), 0.0, 1.0)
            dist = np.linalg.norm(rel - (d_rel + f[:, None] * seg), axis=1)
            return dist <= DOCK_TUBE_M
    return np.zeros(t_s.size, dtype=bool)


def separation_summary(plan: Plan, scenario: Scenario, *, t_s: np.ndarray | None = None) -> dict:
    """Smallest centre distance over non-dock pairs (and over docking pairs), m; None if < 2 vehicles."""
    t_s = plan.t_s if t_s is None else t_s
    pos = plan.positions_at(t_s)
    names = list(plan.vehicles)
    best, best_dock = None, None
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            d = np.linalg.norm(pos[a] - pos[b], axis=1)
            ex = _dock_exempt(plan, scenario, a, b, pos, t_s)
            if (~ex).any():
                m = float(d[~ex].min())
                best = m if best is None else min(best, m)
            if ex.any():
                m = float(d[ex].min())
                best_dock = m if best_dock is None else min(best_dock, m)
    return {"min_separation_m": best, "min_dock_separation_m": best_dock}


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    idx = np.flatnonzero(mask)
    if idx.size == 0:
        return []
    breaks = np.flatnonzero(np.diff(idx) > 1)
    starts = np.concatenate([[idx[0]], idx[breaks + 1]])
    ends = np.concatenate([idx[breaks], [idx[-1]]])
    return list(zip(starts.tolist(), ends.tolist()))


def _add(out: list, t_s, mask, value, limit, vehicle, kind, detail) -> None:
    for s, e in _runs(mask):
        worst = float(np.max(value[s : e + 1]))
        out.append(Violation(float(t_s[s]), vehicle, kind, f"{detail} (until t={t_s[e]:.2f}s)", worst, float(limit)))


def verify_plan(plan: Plan, scenario: Scenario, *, dt_fine_s: float = 0.01) -> list[Violation]:
    """Every violation of ``plan`` against ``scenario`` (empty list = the plan passes)."""
    out: list[Violation] = []
    missing = [n for n in scenario.vehicles if n not in plan.vehicles]
    for n in missing:
        out.append(Violation(0.0, n, "missing", "vehicle of the scenario has no trajectory in the plan", 1.0, 0.0))
    extra = [n for n in plan.vehicles if n not in scenario.vehicles]
    for n in extra:
        out.append(Violation(0.0, n, "unknown", "vehicle is not in the scenario", 1.0, 0.0))
    if missing or extra:
        return out
    end = float(plan.t_s[-1])
    t = np.arange(0.0, end + dt_fine_s / 2, dt_fine_s)
    pos = plan.positions_at(t)
    lim = scenario.limits
    lo, hi = scenario.workspace_min_m, scenario.workspace_max_m
    names = list(plan.vehicles)
    for name in names:
        task = scenario.vehicles[name]
        p = pos[name]
        rb = task.vehicle.body_radius_m
        # workspace: the body disc inside the box horizontally, the centre inside vertically
        below_lo = np.max(np.column_stack([lo[0] + rb - p[:, 0], lo[1] + rb - p[:, 1], lo[2] - p[:, 2]]), axis=1)
        above_hi = np.max(np.column_stack([p[:, 0] + rb - hi[0], p[:, 1] + rb - hi[1], p[:, 2] - hi[2]]), axis=1)
        excess = np.maximum(below_lo, above_hi)
        _add(out, t, excess > 1e-6, excess, 0.0, name, "workspace", "body leaves the workspace by (m)")
        for i, box in enumerate(scenario.obstacles):
            gap_xy = np.hypot(np.maximum(0, np.maximum(box.min_m[0] - p[:, 0], p[:, 0] - box.max_m[0])),
                              np.maximum(0, np.maximum(box.min_m[1] - p[:, 1], p[:, 1] - box.max_m[1])))
            inside_z = (p[:, 2] >= box.min_m[2]) & (p[:, 2] <= box.max_m[2])
            pen = rb - gap_xy
            _add(out, t, inside_z & (pen > 1e-6), pen, 0.0, name, "obstacle", f"body overlaps obstacles[{i}] by (m)")
        # kinematics on the plan grid
        tr = plan.vehicles[name]
        speed = np.linalg.norm(tr.velocity_mps, axis=1)
        _add(out, tr.t_s, speed > task.max_speed_mps * KINEMATIC_TOLERANCE + 1e-3, speed, task.max_speed_mps, name, "speed", "speed (m/s)")
        acc = np.linalg.norm(tr.acceleration_mps2, axis=1)
        _add(out, tr.t_s, acc > task.max_accel_mps2 * KINEMATIC_TOLERANCE + 1e-3, acc, task.max_accel_mps2, name, "acceleration", "acceleration (m/s^2)")
        if tr.t_s.size > 1:
            jerk = np.linalg.norm(np.diff(tr.acceleration_mps2, axis=0), axis=1) / np.diff(tr.t_s)
            _add(out, tr.t_s[1:], jerk > task.max_jerk_mps3 * 1.1 + 1e-3, jerk, task.max_jerk_mps3, name, "jerk", "jerk from finite differences (m/s^3)")
        # goal / hover / dock
        final = p[-1]
        if task.goal_m is not None:
            err = np.linalg.norm(final - task.goal_m)
            if err > GOAL_TOLERANCE_M:
                out.append(Violation(end, name, "goal", f"ends at {np.round(final, 3).tolist()}, goal {task.goal_m.tolist()}", float(err), GOAL_TOLERANCE_M))
        elif task.hover:
            err = np.linalg.norm(p - task.start_m, axis=1)
            _add(out, t, err > GOAL_TOLERANCE_M, err, GOAL_TOLERANCE_M, name, "hover", "drifts from its hover point (m)")
        else:
            want = pos[task.dock_with][-1] + task.dock_offset_m
            err = np.linalg.norm(final - want)
            if err > GOAL_TOLERANCE_M:
                out.append(Violation(end, name, "dock", f"ends {err:.3f} m from {task.dock_with} + offset {task.dock_offset_m.tolist()}", float(err), GOAL_TOLERANCE_M))
        if speed.size and speed[-1] > 0.05:
            out.append(Violation(end, name, "not-at-rest", "still moving at the end of the plan (m/s)", float(speed[-1]), 0.05))
    # pairs: separation and invalid zone
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            va, vb = scenario.vehicles[a].vehicle, scenario.vehicles[b].vehicle
            d = np.linalg.norm(pos[a] - pos[b], axis=1)
            sep = max(lim.min_separation_m, va.body_radius_m + vb.body_radius_m)
            ex = _dock_exempt(plan, scenario, a, b, pos, t)
            short = (d < sep - 1e-6) & ~ex
            _add(out, t, short, sep - d, sep, a, "separation", f"closer than {sep:.3f} m to {b} by (m)")
            if lim.invalid_zone_rule == "model":
                continue
            for tgt, src in ((a, b), (b, a)):
                vs, vt = scenario.vehicles[src].vehicle, scenario.vehicles[tgt].vehicle
                off = pos[tgt] - pos[src]
                dz = -off[:, 2]
                r = np.hypot(off[:, 0], off[:, 1])
                inside = (dz > 1e-6) & (dz <= VALIDITY_FACTOR_L * vs.size_m) & (r < vs.body_radius_m + vt.body_radius_m) & ~ex
                _add(out, t, inside, VALIDITY_FACTOR_L * vs.size_m - dz, 0.0, tgt, "invalid-zone",
                     f"below {src} inside its invalid zone (dz <= 3 L, footprints overlap); depth (m)")
    # authority usage from the model directly
    along = wrench_along_plan(plan, scenario, t_s=t)
    for name, w in along.items():
        over = w.usage > lim.authority_fraction + USAGE_TOLERANCE
        if over.any():
            worst_src = max(w.usage_by_source.items(), key=lambda kv: float(np.max(np.where(over, kv[1], 0.0))), default=(None, None))[0]
            _add(out, t, over, w.usage, lim.authority_fraction, name, "authority", f"authority usage in the downwash of {worst_src}")
    out.sort(key=lambda v: (v.t_s, v.vehicle, v.kind))
    return out


def scenario_of_plan(plan: Plan, *, label: str = "plan.json") -> Scenario:
    """The scenario a plan was made for: its embedded copy, else its scenario file."""
    from fileio.errors import UserError
    from planfile.scenario import load_scenario, scenario_from_dict

    if plan.scenario_spec is not None and plan.format_version >= 2:
        return scenario_from_dict(plan.scenario_spec, vehicle_types=plan.vehicle_types)
    if plan.scenario_spec is not None:
        return scenario_from_dict(plan.scenario_spec, source_path=plan.scenario_file or None)
    if plan.scenario_file:
        return load_scenario(plan.scenario_file)
    raise UserError(f"{label}: scenario_spec / scenario_file: missing; pass the scenario with --scenario FILE.yaml")
