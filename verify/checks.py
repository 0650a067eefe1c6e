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
   (a vehicle flown closed-loop may be that far off its plan; a resting one is not). Every
   vehicle's predicted growth d (``deflection_along_plan``: its tracking error along its own
   reference and its closed loop in the jets the model predicts on it, :mod:`proxplan.verify.jet_loop`)
   is part of its tube, moving or not: the pair's tube is t + d_a + d_b.
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
from proxplan.physics import one_blas_thread
from proxplan.planfile import Plan, Scenario, load_scenario, scenario_from_dict
from proxplan.verify.along import plan_samples, wrench_along_plan
from proxplan.verify.jet_loop import check_jet_loop, loop_along_plan
from proxplan.verify.memo import VerifyMemo
from proxplan.verify.pair_checks import check_authority, check_authority_tube, check_pairs, tube_offsets
from proxplan.verify.tolerances import (
    GOAL_TOLERANCE_M,
    JERK_TOLERANCE,
    KINEMATIC_TOLERANCE,
    POSITION_CONSISTENCY_M,
    REST_SPEED_MPS,
    USAGE_TOLERANCE,
    VELOCITY_CONSISTENCY_MPS,
)
from proxplan.verify.violations import Violation, add_runs

# the verifier's answer for the plan it checked last (verify_with_deflections)
LAST = VerifyMemo()

__all__ = [
    "GOAL_TOLERANCE_M",
    "REST_SPEED_MPS",
    "USAGE_TOLERANCE",
    "check_authority",
    "check_authority_tube",
    "check_pairs",
    "scenario_of_plan",
    "tube_offsets",
    "verify_plan",
]


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


def verify_plan(plan: Plan, scenario: Scenario, *, dt_fine_s: float = 0.01) -> list[Violation]:
    """Every violation of ``plan`` against ``scenario`` (empty list = the plan passes), sorted by
    time; the model checks run on a grid of step ``dt_fine_s``, s (:func:`verify_with_deflections`)."""
    return verify_with_deflections(plan, scenario, dt_fine_s=dt_fine_s)[0]


def verify_with_deflections(
    plan: Plan, scenario: Scenario, *, dt_fine_s: float = 0.01
) -> tuple[list[Violation], dict[str, np.ndarray]]:
    """:func:`verify_plan`'s violations and, per vehicle the loops along the plan were run for, the predicted
    deflection (M,) m on the grid 0, dt_fine_s, ... (``deflection_along_plan``'s, unclipped; empty when the
    plan fails before the model checks): what the planners' deflection policy grows the tubes by, without
    running the loops a second time. Asked about the plan it checked last (the same scenario object, the
    same sampled trajectories and step), it gives that answer back, not computed again
    (:class:`proxplan.verify.memo.VerifyMemo`: the swarm layer's guard and the pipeline verify the same
    repaired plan)."""
    return LAST.get(plan, scenario, dt_fine_s, lambda: _verified(plan, scenario, dt_fine_s))


@one_blas_thread
def _verified(plan: Plan, scenario: Scenario, dt_fine_s: float) -> tuple[list[Violation], dict[str, np.ndarray]]:
    """:func:`verify_with_deflections` computed. Run with one BLAS thread
    (:func:`proxplan.physics.one_blas_thread`): the loops along the plan are many small matrix
    products, which OpenBLAS's threads slow down (corridor-64: 9.6 -> 4.3 s of CPU)."""
    out = _check_vehicles(plan, scenario)
    if out:
        return out, {}
    out = _check_consistency(plan, scenario)
    t = np.arange(0.0, float(plan.t_s[-1]) + dt_fine_s / 2, dt_fine_s)
    samples = plan_samples(plan, t)  # sampled once, shared by the checks
    pos = {n: s[0] for n, s in samples.items()}
    out += _check_tasks(plan, scenario, t, pos)
    along = wrench_along_plan(plan, scenario, t_s=t, samples=samples)
    loops = loop_along_plan(plan, scenario, along, samples=samples)
    out += check_jet_loop(loops, t, plan.t_s, scenario.limits.min_separation_m)
    # the pair checks with each tube grown by at most the separation (a growth beyond it is a violation)
    far = scenario.limits.min_separation_m
    deflection = {n: np.minimum(loops[n].deflection_m, far) if n in loops else np.zeros(t.size) for n in along}
    out += check_pairs(plan, scenario, t, samples, deflection)
    out += check_authority(scenario, t, along, plan.t_s)
    if not any(v.kind == "authority" for v in out):  # the plain check names the cause first
        out += check_authority_tube(plan, scenario, t, samples, deflection)
    out.sort(key=lambda v: (v.t_s, v.vehicle, v.kind))
    return out, {n: loop.deflection_m for n, loop in loops.items()}


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
