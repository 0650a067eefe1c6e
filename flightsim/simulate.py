"""Closed-loop flight of a multi-vehicle plan with downwash, on RotorPy's dynamics.

Each vehicle is RotorPy's multirotor model (:mod:`proxplan.flightsim.dynamics`, parameters from
:mod:`proxplan.flightsim.vehicle_params`) flown by a tracking controller (``SimulationOptions.controller``):

* ``"mellinger"`` (default): the Crazyflie firmware's Mellinger law (:mod:`proxplan.flightsim.mellinger`)
  at 500 Hz with the firmware's gains (scaled by mass and inertia for other types), set-points
  (position, velocity, acceleration and the body-rate feed-forward from the reference jerk) sampled
  from the plan at 100 Hz and held, motor commands capped as the firmware's power distribution does;
* ``"rotorpy"``: RotorPy's SE(3) controller (:mod:`proxplan.flightsim.control`) tracking position,
  velocity and acceleration every physics step, no rate feed-forward.

Both fly yaw 0. Every physics step (default
500 Hz) each vehicle receives the external wrench of :func:`proxplan.physics.effects.total_wrench`: the
base downwash model (S0-3..S0-8) of every other vehicle plus the "truth" effects.

Frames: world z up, ground plane at z = ``ground_z_m``; the model wrench is computed for level
vehicles (world = body axes, as in proxplan.physics.disturbance): its force is applied in the world frame,
its torque rotated into the body frame.

Speed: the wrench is evaluated for ``wrench_horizon_steps`` physics steps at once, at the positions
predicted from the current state (x + v tau + a tau^2 / 2, a from the last step), so each physics
step still gets its own wrench while the model is called once per horizon (``wrench_horizon_steps=1``
evaluates it at the exact state of every step).
"""

from __future__ import annotations

import enum
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from proxplan.fileio import UserError
from proxplan.flightsim.imu import ImuOptions, imu_samples
from proxplan.flightsim.mellinger import controller_gains, reference_body_rates
from proxplan.flightsim.stepper import CompiledStepper
from proxplan.flightsim.truth import TruthSpec, merge_truth, plan_truth
from proxplan.flightsim.vehicle_params import quad_params
from proxplan.physics import (
    TARGET_ONLY_EFFECTS,
    Effect,
    EffectInputs,
    ModelOptions,
    SourceSample,
    Vehicle,
    total_wrench,
)
from proxplan.planfile import Plan, read_plan


@dataclass(frozen=True)
class SimulationOptions:
    physics_dt_s: float = 0.002  # RK4 step of the dynamics and controller period, s
    log_dt_s: float = 0.01  # log / record period, s (a multiple of physics_dt_s)
    settle_s: float = 1.0  # hover at the final reference after the plan ends, s
    wrench_horizon_steps: int = 10  # physics steps per batched wrench evaluation, -
    imu_noise: bool = True  # white noise on the logged IMU samples
    imu: ImuOptions = ImuOptions()
    mocap_noise_std_m: float = 0.0005  # noise of the logged positions, m
    velocity_noise_std_mps: float = 0.005  # noise of the logged velocities, m/s
    ground_z_m: float = 0.0  # ground plane height, world frame, m
    seed: int = 0
    position_integral_rate_ps: float = 0.0  # integral action k_i / k_p per axis, 1/s (0 = RotorPy's PD)
    position_integral_limit_ms: float = 0.2  # anti-windup bound of the integrated position error, m s
    feedforward: bool = False  # compensate the plan's predicted disturbance wrench in the controller
    controller: str = "mellinger"  # "mellinger" (Crazyflie firmware law) or "rotorpy" (RotorPy's SE(3))
    rate_feedforward: bool = True  # Mellinger: body-rate feed-forward from the reference jerk
    setpoint_rate_hz: float = 100.0  # Mellinger: set-point evaluation rate (held in between), Hz


@dataclass(frozen=True)
class Perturbation:
    """Per-flight departures of the flown world from the plan (``proxplan certify`` draws them),
    keyed by vehicle name; vehicles not named fly unperturbed. Functions take times since the plan
    start (K,), s, and return (K, 3) arrays, world frame.

    * ``start_offset_m``: start position error, m (the vehicle starts off its reference);
    * ``time_offset_s``: timing error, s: the vehicle follows its plan late by this (early if < 0);
    * ``force_N``: residual disturbance force beyond the model, N (applied and counted in the
      applied wrench, so authority usage includes it);
    * ``estimate_error_m`` / ``estimate_error_mps``: error of the position / velocity estimate the
      controller sees, m and m/s. The SE(3) law uses only x - x_ref and v - v_ref, so an estimate
      x + n is flown exactly as the reference x_ref - n, which is how it is applied.
    """

    start_offset_m: Mapping[str, Sequence[float]] = field(default_factory=dict)
    time_offset_s: Mapping[str, float] = field(default_factory=dict)
    force_N: Mapping[str, Callable[[np.ndarray], np.ndarray]] = field(default_factory=dict)
    estimate_error_m: Mapping[str, Callable[[np.ndarray], np.ndarray]] = field(default_factory=dict)
    estimate_error_mps: Mapping[str, Callable[[np.ndarray], np.ndarray]] = field(default_factory=dict)


@dataclass(frozen=True)
class VehicleRecord:
    """One vehicle's flight sampled every ``log_dt_s`` (M samples). World frame unless noted."""

    name: str
    type_name: str
    vehicle: Vehicle
    t_s: np.ndarray  # (M,) since the plan start, s
    position_m: np.ndarray  # (M, 3) true
    velocity_mps: np.ndarray  # (M, 3) true
    acceleration_mps2: np.ndarray  # (M, 3) true (gravity excluded)
    q_xyzw: np.ndarray  # (M, 4) body to world
    w_body_radps: np.ndarray  # (M, 3) true body rates, body frame
    ref_position_m: np.ndarray  # (M, 3)
    ref_velocity_mps: np.ndarray  # (M, 3)
    motor_thrust_N: np.ndarray  # (M, 4) actual k_eta omega^2, (S0-14) order
    cmd_motor_thrust_N: np.ndarray  # (M, 4) commanded by the controller (unclipped)
    cmd_thrust_N: np.ndarray  # (M,) commanded collective thrust
    cmd_moment_Nm: np.ndarray  # (M, 3) commanded body moments, body frame
    saturated: np.ndarray  # (M,) bool: a motor command was clipped at this sample
    accel_meas_body_mps2: np.ndarray  # (M, 3) IMU specific force, body frame
    gyro_meas_radps: np.ndarray  # (M, 3) IMU gyro, body frame
    applied_force_N: np.ndarray  # (M, 3) external force applied (model + truth effects)
    applied_torque_Nm: np.ndarray  # (M, 3) external torque applied, world axes
    model_force_N: np.ndarray  # (M, 3) base model part only (no truth effects)
    model_torque_Nm: np.ndarray  # (M, 3)
    predicted_force_N: np.ndarray | None = None  # (M, 3) the plan's predicted disturbance, world frame, N
    predicted_torque_Nm: np.ndarray | None = None  # (M, 3) world axes, N m

    @property
    def accel_meas_world_mps2(self) -> np.ndarray:
        """IMU specific force rotated into the world frame (M, 3), m/s^2 (~ +9.81 on z in hover)."""
        from scipy.spatial.transform import Rotation

        return Rotation.from_quat(self.q_xyzw).apply(self.accel_meas_body_mps2)


class SimulationStatus(enum.Enum):
    """How a simulation ended (a result, like RotorPy's ExitStatus; not a user error)."""

    COMPLETE = "complete"  # flown to the end of the plan plus settle_s
    DIVERGED = "diverged"  # a vehicle's state became non-finite: it lost control; records stop before


@dataclass(frozen=True)
class SimulationResult:
    scenario: str
    options: SimulationOptions
    truth: TruthSpec
    plan_duration_s: float  # the plan's own duration; records run settle_s longer, s
    records: dict[str, VehicleRecord]
    saturation_time_s: dict[str, float]  # physics-step time with any motor command clipped, s
    wall_time_s: float
    sim_time_s: float
    notes: list[str] = field(default_factory=list)
    status: SimulationStatus = SimulationStatus.COMPLETE
    status_detail: str = ""  # what ended the flight when it did not complete

    @property
    def real_time_factor(self) -> float:
        return self.sim_time_s / max(self.wall_time_s, 1e-9)


def simulate_plan(
    plan: Plan | str | Path,
    *,
    truth_effects: Sequence[Effect] = (),
    truth: TruthSpec | None = None,
    vehicles: Mapping[str, Vehicle] | None = None,
    seed: int = 0,
    physics_dt_s: float = 0.002,
    log_dt_s: float = 0.01,
    imu_noise: bool = True,
    settle_s: float = 1.0,
    wrench_horizon_steps: int = 10,
    position_integral_rate_ps: float = 0.0,
    controller: str = "mellinger",
    options: SimulationOptions | None = None,
    progress: bool = False,
    perturbation: Perturbation | None = None,
) -> SimulationResult:
    """Fly ``plan`` (a :class:`proxplan.planfile.plan.Plan` or a plan.json path) closed loop.

    ``truth`` (or just ``truth_effects``) adds effects beyond the model; without ``truth`` the world
    is :func:`proxplan.flightsim.truth.plan_truth` (the plan's field form and effects) plus ``truth_effects``
    (give ``truth=merge_truth(plan_truth(plan), extra)`` to add to the plan's effects); ``vehicles`` maps type
    names to the vehicles actually flown instead of the plan's own parameters (e.g. a heavier or
    weaker airframe than planned). ``options``, when given, overrides the keyword numbers.
    ``perturbation`` (:class:`Perturbation`) adds start, timing, residual-force and estimate errors.

    Controller: ``options.controller`` (module docstring; the Mellinger law has its own integrators).
    ``position_integral_rate_ps`` > 0 adds integral action on the
    position error, as the seed's cascaded PID (S0 IV-D). With diagonal gains,
    k_p e + k_i int(e) dt = k_p (e + (k_i / k_p) int(e) dt), so the integral enters as a shift of the
    position reference fed to the controller; the integrated error is clipped to
    +-``position_integral_limit_ms`` (anti-windup).
    """
    if isinstance(plan, (str, Path)):
        plan = read_plan(plan)
    if truth is None:  # the world the plan was made for (its calibrated effects too) + truth_effects
        truth = merge_truth(plan_truth(plan), TruthSpec(effects=tuple(truth_effects)), extra_form=False)
    elif truth_effects:
        truth = TruthSpec(tuple(truth.effects) + tuple(truth_effects), truth.wind_mps, truth.field_form)
    if options is None:
        options = SimulationOptions(
            physics_dt_s=physics_dt_s,
            log_dt_s=log_dt_s,
            settle_s=settle_s,
            wrench_horizon_steps=wrench_horizon_steps,
            imu_noise=imu_noise,
            seed=seed,
            position_integral_rate_ps=position_integral_rate_ps,
            controller=controller,
        )
    dt = options.physics_dt_s
    log_every = int(round(options.log_dt_s / dt))
    if dt <= 0 or log_every < 1 or abs(log_every * dt - options.log_dt_s) > 1e-9:
        raise UserError(f"log_dt_s ({options.log_dt_s} s) must be a positive multiple of physics_dt_s ({dt} s)")
    horizon = max(1, int(options.wrench_horizon_steps))

    names = list(plan.vehicles)
    trajs = [plan.vehicles[n] for n in names]
    vehs = [(vehicles or {}).get(t.type_name, t.vehicle) for t in trajs]
    n_veh = len(names)
    params = [quad_params(v) for v in vehs]
    model_options = ModelOptions(field_form=truth.field_form)
    effects = tuple(truth.effects)

    t0 = min(float(t.t_s[0]) for t in trajs)
    t_end = max(float(t.t_s[-1]) for t in trajs)
    plan_duration = t_end - t0
    n_steps = int(round((plan_duration + options.settle_s) / dt / log_every)) * log_every + 1
    t_grid = t0 + dt * np.arange(n_steps)
    pert = perturbation or Perturbation()
    shifts = np.array([float(pert.time_offset_s.get(n, 0.0)) for n in names])
    refs = [tr.sample(t_grid - shift) for shift, tr in zip(shifts, trajs)]
    if options.controller not in CONTROLLERS:
        raise UserError(f"controller: expected one of {', '.join(CONTROLLERS)}, got {options.controller!r}")
    mellinger = options.controller == "mellinger"
    if mellinger:  # the firmware evaluates the trajectory at its set-point rate and holds it
        if options.setpoint_rate_hz <= 0:
            raise UserError(f"setpoint_rate_hz: expected a positive rate, Hz, got {options.setpoint_rate_hz}")
        t_sp = t0 + np.floor((t_grid - t0) * options.setpoint_rate_hz + 1e-9) / options.setpoint_rate_hz
    else:
        t_sp = t_grid
    sp = [tr.sample(t_sp - shift) for shift, tr in zip(shifts, trajs)]
    ref_w = np.zeros((n_steps, n_veh, 3))  # body-rate feed-forward, body frame, rad/s
    if mellinger and options.rate_feedforward:
        for vi, (shift, tr) in enumerate(zip(shifts, trajs)):
            ref_w[:, vi] = reference_body_rates(sp[vi][2], tr.jerk_at(t_sp - shift))
    notes: list[str] = []
    # what the plan predicted, on each vehicle's (possibly late) plan time
    pred_f, pred_t, ff_note = predicted_wrench(plan, names, t_grid[:, None] - shifts[None, :])
    ff_f = ff_t = None
    if options.feedforward:
        ff_f, ff_t = pred_f, pred_t
        if ff_note:
            notes.append(ff_note)
    ref_x = np.stack([r[0] for r in refs], axis=1)  # (n_steps, V, 3)
    ref_v = np.stack([r[1] for r in refs], axis=1)
    extra_f = np.zeros((n_steps, n_veh, 3))  # residual force beyond the model, N
    ctrl_ref = np.concatenate(
        [np.stack([r[d] for r in sp], axis=1) for d in range(3)] + [ref_w], axis=2
    )  # (n_steps, V, 12): the set-points the controller sees
    for vi, n in enumerate(names):
        if n in pert.force_N:
            extra_f[:, vi] = pert.force_N[n](t_grid - t0)
        if n in pert.estimate_error_m:
            ctrl_ref[:, vi, 0:3] -= pert.estimate_error_m[n](t_grid - t0)
        if n in pert.estimate_error_mps:
            ctrl_ref[:, vi, 3:6] -= pert.estimate_error_mps[n](t_grid - t0)

    hover_speed = np.array([np.sqrt(v.hover_thrust_per_rotor_N / p["k_eta"]) for v, p in zip(vehs, params)])
    gains = [controller_gains(v) if mellinger else None for v in vehs]
    stepper = _stepper(params, dt, truth.wind_mps, gains)
    stepper.ctrl_mem[:] = 0.0  # fresh controller memory (integrators) for this flight
    S = stepper.state
    S[:] = 0.0
    stepper.ff_force_N[:] = 0.0  # the stepper is cached: no feed-forward left from an earlier flight
    stepper.ff_torque_Nm[:] = 0.0
    S[:, 0:3] = ref_x[0] + np.array([pert.start_offset_m.get(n, (0.0, 0.0, 0.0)) for n in names], dtype=float)
    S[:, 3:6] = ref_v[0]
    S[:, 9] = 1.0  # identity attitude, [x, y, z, w]
    S[:, 13:17] = hover_speed[:, None]
    # the vehicles start at their reference with hover rotor speeds and reject from t0 whatever acts on them

    n_log = (n_steps - 1) // log_every + 1
    rec = {
        key: np.zeros((n_log, n_veh) + shape)
        for key, shape in (
            ("x", (3,)),
            ("v", (3,)),
            ("a", (3,)),
            ("q", (4,)),
            ("w", (3,)),
            ("rx", (3,)),
            ("rv", (3,)),
            ("f", (4,)),
            ("fc", (4,)),
            ("T", ()),
            ("M", (3,)),
            ("acc", (3,)),
            ("gyr", (3,)),
            ("Fa", (3,)),
            ("Ta", (3,)),
            ("Fm", (3,)),
            ("Tm", (3,)),
        )
    }
    rec_sat = np.zeros((n_log, n_veh), dtype=bool)
    sat_steps = np.zeros(n_veh)
    k_eta = np.array([p["k_eta"] for p in params])[:, None]

    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=n_steps, desc="simulate", unit="step", unit_scale=True, leave=False)
    wall_start = time.perf_counter()
    acc_est = np.zeros((n_veh, 3))
    buf_f = np.zeros((n_veh, horizon, 3))
    buf_t = np.zeros((n_veh, horizon, 3))
    tau = dt * np.arange(horizon)
    ref_all = ctrl_ref  # (n_steps, V, 12)
    integral_ms = np.zeros((n_veh, 3))  # integrated position error, m s
    ki_rate = float(options.position_integral_rate_ps)
    windup = float(options.position_integral_limit_ms)
    status, status_detail = SimulationStatus.COMPLETE, ""
    n_logged = n_log
    try:
        for k in range(n_steps):
            j = k % horizon
            if j == 0:
                _fill_wrench(
                    buf_f, buf_t, S[:, 0:3], S[:, 3:6], acc_est, tau, vehs, effects, model_options, options.ground_z_m
                )
            stepper.ref[:] = ref_all[k]
            if ki_rate > 0.0:
                integral_ms += (S[:, 0:3] - ref_all[k][:, 0:3]) * dt
                np.clip(integral_ms, -windup, windup, out=integral_ms)
                stepper.ref[:, 0:3] -= ki_rate * integral_ms
            stepper.ext_force_N[:] = buf_f[:, j] + extra_f[k]
            stepper.ext_torque_Nm[:] = buf_t[:, j]
            if ff_f is not None and ff_t is not None:
                stepper.ff_force_N[:] = ff_f[k]
                stepper.ff_torque_Nm[:] = ff_t[k]
            stepper.step()
            sat_steps += stepper.saturated
            if k % log_every == 0:
                i = k // log_every
                for key, val in (
                    ("x", S[:, 0:3]),
                    ("v", S[:, 3:6]),
                    ("a", stepper.accel_mps2),
                    ("q", S[:, 6:10]),
                    ("w", S[:, 10:13]),
                    ("rx", ref_x[k]),
                    ("rv", ref_v[k]),
                    ("f", k_eta * S[:, 13:17] ** 2),
                    ("fc", stepper.cmd_thrust_N),
                    ("T", stepper.ctbm[:, 0]),
                    ("M", stepper.ctbm[:, 1:4]),
                    ("Fa", buf_f[:, j] + extra_f[k]),
                    ("Ta", buf_t[:, j]),
                ):
                    rec[key][i] = val
                rec_sat[i] = stepper.saturated > 0.5
            acc_est = (stepper.next_state[:, 3:6] - S[:, 3:6]) / dt
            stepper.advance()
            if not np.all(np.isfinite(S)):
                lost = [names[v] for v in range(n_veh) if not np.all(np.isfinite(S[v]))]
                status = SimulationStatus.DIVERGED
                status_detail = f"{', '.join(lost)} lost control at t = {t_grid[k] - t0:.3f} s (state not finite)"
                n_logged = k // log_every + 1  # rows logged up to step k hold finite states
                break
            if bar is not None and k % 500 == 0:
                bar.update(min(500, n_steps - k))
    finally:
        if bar is not None:
            bar.close()
    if n_logged < n_log:  # keep the finite part of a diverged flight
        rec = {key: arr[:n_logged] for key, arr in rec.items()}
        rec_sat = rec_sat[:n_logged]
    rng = np.random.default_rng(options.seed)
    for vi in range(n_veh):
        rec["acc"][:, vi], rec["gyr"][:, vi] = imu_samples(
            rec["q"][:, vi],
            rec["w"][:, vi],
            rec["a"][:, vi],
            options=options.imu,
            rng=rng,
            with_noise=options.imu_noise,
        )
    wall = time.perf_counter() - wall_start

    # base-model part of the applied wrench at the logged states (differs only with truth effects)
    if effects:
        for vi in range(n_veh):
            f, t = _wrench_for(vi, rec["x"][:, :, :], rec["v"][:, vi], vehs, (), model_options, options.ground_z_m)
            rec["Fm"][:, vi] = f
            rec["Tm"][:, vi] = t
    else:
        rec["Fm"][:] = rec["Fa"] - extra_f[::log_every][:n_logged]
        rec["Tm"][:] = rec["Ta"]

    t_log = (t_grid[::log_every] - t0)[:n_logged]
    records: dict[str, VehicleRecord] = {}
    for vi, name in enumerate(names):
        records[name] = VehicleRecord(
            name=name,
            type_name=trajs[vi].type_name,
            vehicle=vehs[vi],
            t_s=t_log,
            position_m=rec["x"][:, vi],
            velocity_mps=rec["v"][:, vi],
            acceleration_mps2=rec["a"][:, vi],
            q_xyzw=rec["q"][:, vi],
            w_body_radps=rec["w"][:, vi],
            ref_position_m=rec["rx"][:, vi],
            ref_velocity_mps=rec["rv"][:, vi],
            motor_thrust_N=rec["f"][:, vi],
            cmd_motor_thrust_N=rec["fc"][:, vi],
            cmd_thrust_N=rec["T"][:, vi],
            cmd_moment_Nm=rec["M"][:, vi],
            saturated=rec_sat[:, vi],
            accel_meas_body_mps2=rec["acc"][:, vi],
            gyro_meas_radps=rec["gyr"][:, vi],
            applied_force_N=rec["Fa"][:, vi],
            applied_torque_Nm=rec["Ta"][:, vi],
            model_force_N=rec["Fm"][:, vi],
            model_torque_Nm=rec["Tm"][:, vi],
            predicted_force_N=pred_f[::log_every][:n_logged, vi],
            predicted_torque_Nm=pred_t[::log_every][:n_logged, vi],
        )
    for name, record in records.items():
        low = float(record.position_m[:, 2].min())
        if low < options.ground_z_m:
            notes.append(f"{name} went below the ground plane (min z = {low:.3f} m): ground contact is not modelled")
    return SimulationResult(
        notes=notes,
        scenario=str(plan.scenario),
        options=options,
        truth=truth,
        plan_duration_s=plan_duration,
        records=records,
        saturation_time_s={n: float(sat_steps[i] * dt) for i, n in enumerate(names)},
        wall_time_s=wall,
        sim_time_s=float(t_log[-1]) if n_logged else 0.0,
        status=status,
        status_detail=status_detail,
    )


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


_STEPPER_CACHE: dict = {}
CONTROLLERS = ("mellinger", "rotorpy")
"""Names of the simulated tracking controllers (``SimulationOptions.controller``)."""


def _stepper(params: list[dict], dt_s: float, wind_mps, gains: list) -> CompiledStepper:
    """A compiled stepper for these vehicles (cached: building one takes ~0.1 s per vehicle)."""
    key = (repr(params), float(dt_s), tuple(float(w) for w in wind_mps), repr(gains))
    if key not in _STEPPER_CACHE:
        if len(_STEPPER_CACHE) > 16:
            _STEPPER_CACHE.clear()
        _STEPPER_CACHE[key] = CompiledStepper(params, dt_s, wind_mps=wind_mps, controllers=gains)
    return _STEPPER_CACHE[key]


def _wrench_for(
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


def _fill_wrench(
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
    pred_x = x[None] + tau[:, None, None] * v[None] + 0.5 * tau[:, None, None] ** 2 * acc[None]
    pred_v = v[None] + tau[:, None, None] * acc[None]  # (K, V, 3)
    for i in range(len(vehs)):
        f, t = _wrench_for(i, pred_x, pred_v[:, i], vehs, effects, model_options, ground_z_m)
        buf_f[i] = f
        buf_t[i] = t
