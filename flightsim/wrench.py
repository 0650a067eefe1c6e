"""The disturbance on each simulated vehicle: the wrench the world applies (the base downwash model of
every other vehicle, S0-3..S0-8, plus the "truth" effects, :func:`proxplan.physics.effects.total_wrench`)
and the wrench the plan predicted (feed-forward, reports).

Frames: world z up; the model wrench is computed for level vehicles (world = body axes, as in
proxplan.physics.disturbance): its force in the world frame, its torque about world axes.

Speed: :func:`fill_horizon` evaluates the wrench for a horizon of physics steps at once, at the
positions predicted from the current state (x + v tau + a tau^2 / 2), so each physics step still
gets its own wrench while the model is called once per horizon.
"""

from __future__ import annotations

import numpy as np

from proxplan.physics import TARGET_ONLY_EFFECTS, EffectInputs, ModelOptions, SourceSample, Vehicle, total_wrench


def predicted_wrench(plan, names: list[str], t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, str]:
    """The plan's predicted disturbance force (K, V, 3), N, and torque (K, V, 3), N m (world frame)
    at plan times ``t_s`` ((K,) or per vehicle (K, V)), linear between plan samples and held outside
    the plan, and a note: the
    plan's feed-forward fields, or, when a plan has none (older files), the wrench recomputed with
    the verifier's model (``proxplan.verify.wrench_along_plan``, the scenario's model options)."""
    from proxplan.verify import scenario_of_plan, wrench_along_plan

    trajs = [plan.vehicles[n] for n in names]
    note = ""
    if not all(getattr(tr, "disturbance_force_N", None) is not None for tr in trajs):
        has_scenario = getattr(plan, "scenario_spec", None) is not None or getattr(plan, "scenario_file", None)
        scenario = scenario_of_plan(plan) if has_scenario else None
        along = wrench_along_plan(plan, scenario, t_s=trajs[0].t_s)
        forces = [along[n].force_N for n in names]
        torques = [along[n].torque_Nm for n in names]
        note = (
            "the plan has no feed-forward fields (disturbance_force_N / disturbance_torque_Nm; an older plan.json): "
            "recomputed with the verifier's model"
        )
    else:
        forces = [tr.disturbance_force_N for tr in trajs]
        torques = [tr.disturbance_torque_Nm for tr in trajs]
    t_kv = np.asarray(t_s, dtype=float)
    if t_kv.ndim == 1:
        t_kv = np.repeat(t_kv[:, None], len(names), axis=1)
    f = np.zeros((t_kv.shape[0], len(names), 3))
    tq = np.zeros_like(f)
    for vi, tr in enumerate(trajs):
        for d in range(3):
            f[:, vi, d] = np.interp(t_kv[:, vi], tr.t_s, forces[vi][:, d])
            tq[:, vi, d] = np.interp(t_kv[:, vi], tr.t_s, torques[vi][:, d])
    return f, tq, note


def wrench_on(
    target_index: int,
    positions_m: np.ndarray,
    velocity_mps: np.ndarray,
    vehs: list[Vehicle],
    effects: tuple,
    model_options: ModelOptions,
    ground_z_m: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Wrench (K, 3) x2 on vehicle ``target_index`` for positions (K, V, 3) of all vehicles and the
    target's velocity (K, 3): :func:`proxplan.physics.effects.total_wrench` with every other vehicle as a
    source. For speed, sources of the same vehicle type are stacked into one model call, and a
    source never above the target over the K samples is skipped (its downwash, and every
    per-source effect, is exactly zero there); target-only effects are evaluated once. Where two or
    more sources are above the target at once (a stack shields, :mod:`proxplan.physics.stack`), those
    sources are evaluated together in one call, never stacked."""
    i = target_index
    k = positions_m.shape[0]
    target = vehs[i]
    height = positions_m[:, i, 2] - ground_z_m
    per_source = tuple(e for e in effects if e.name not in TARGET_ONLY_EFFECTS)
    target_only = tuple(e for e in effects if e.name in TARGET_ONLY_EFFECTS)
    groups: list[tuple[Vehicle, list[np.ndarray]]] = []
    above: list[tuple[Vehicle, np.ndarray]] = []
    for j, src in enumerate(vehs):
        if j == i:
            continue
        offsets = positions_m[:, i] - positions_m[:, j]
        if np.all(offsets[:, 2] >= 0.0):
            continue
        above.append((src, offsets))
    n_above = sum((off[:, 2] < 0.0).astype(int) for _, off in above)
    if np.any(n_above >= 2):  # a stack at some sample: every source above in one call
        inputs = EffectInputs(
            target=target, height_above_ground_m=height, velocity_mps=velocity_mps,
            sources=tuple(SourceSample(v, o) for v, o in above), options=model_options,
        )  # fmt: skip
        force, torque = total_wrench(inputs, per_source)
        above = []
    else:
        force = np.zeros((k, 3))
        torque = np.zeros((k, 3))
    for src, offsets in above:
        for veh, offs in groups:
            if veh == src:
                offs.append(offsets)
                break
        else:
            groups.append((src, [offsets]))
    for src, offs in groups:
        n = len(offs)
        inputs = EffectInputs(
            target=target,
            height_above_ground_m=np.tile(height, n),
            velocity_mps=np.tile(velocity_mps, (n, 1)),
            sources=(SourceSample(src, np.concatenate(offs)),),
            options=model_options,
        )
        f, t = total_wrench(inputs, per_source)
        force += f.reshape(n, k, 3).sum(axis=0)
        torque += t.reshape(n, k, 3).sum(axis=0)
    if target_only:
        inputs = EffectInputs(
            target=target, height_above_ground_m=height, velocity_mps=velocity_mps, sources=(), options=model_options
        )
        f, t = total_wrench(inputs, target_only)
        force += f
        torque += t
    return force, torque


def horizon_states(x: np.ndarray, v: np.ndarray, acc: np.ndarray, tau: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Positions and velocities (K, V, 3), m and m/s, world, predicted at offsets ``tau`` (K,), s, from
    positions, velocities and accelerations (V, 3): x + v tau + a tau^2 / 2 and v + a tau."""
    t = tau[:, None, None]
    return x[None] + t * v[None] + 0.5 * t**2 * acc[None], v[None] + t * acc[None]


def fill_horizon(
    buf_f,
    buf_t,
    x: np.ndarray,
    v: np.ndarray,
    acc: np.ndarray,
    tau: np.ndarray,
    vehs,
    effects,
    model_options,
    ground_z_m,
) -> None:
    """Wrench on every vehicle at the positions predicted over the next horizon from positions,
    velocities and accelerations (V, 3) (buffers (V, K, 3))."""
    pred_x, pred_v = horizon_states(x, v, acc, tau)
    for i in range(len(vehs)):
        f, t = wrench_on(i, pred_x, pred_v[:, i], vehs, effects, model_options, ground_z_m)
        buf_f[i] = f
        buf_t[i] = t
