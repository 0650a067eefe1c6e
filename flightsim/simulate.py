"""Closed-loop flight of a multi-vehicle plan with downwash, on RotorPy's dynamics.

Each vehicle is RotorPy's multirotor model (:mod:`proxplan.flightsim.dynamics`, parameters from
:mod:`proxplan.flightsim.vehicle_params`, rotor drag included) flown by a tracking controller
(``SimulationOptions.controller``):

* ``"mellinger"`` (default): the Crazyflie firmware's Mellinger law (:mod:`proxplan.flightsim.mellinger`)
  at 500 Hz with the vehicle's gains (``Vehicle.controller``), set-points (position, velocity,
  acceleration and the body-rate feed-forward from the reference jerk) sampled at 100 Hz and held,
  motor commands capped as the firmware's power distribution does;
* ``"rotorpy"``: RotorPy's SE(3) controller (:mod:`proxplan.flightsim.control`) tracking position,
  velocity and acceleration every physics step, no rate feed-forward.

By default the set-points compensate rotor drag the way the export does (:mod:`proxplan.flightsim.references`)
and errors are measured against the plan. Both fly yaw 0. Every physics step (default 500 Hz) each
vehicle receives the external wrench of :mod:`proxplan.flightsim.wrench` (the base downwash model of
every other vehicle plus the "truth" effects), evaluated for ``wrench_horizon_steps`` steps at once.
This module wires them together: the world and options (:func:`simulate_plan`), the flight loop
(:func:`_fly`) and the result (:func:`_result`).
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from proxplan.fileio import UserError
from proxplan.flightsim.imu import imu_samples
from proxplan.flightsim.mellinger import controller_gains
from proxplan.flightsim.options import CONTROLLERS, Perturbation, SimulationOptions
from proxplan.flightsim.records import FlightLog, SimulationResult, SimulationStatus
from proxplan.flightsim.references import FlightReferences, flight_references
from proxplan.flightsim.stepper import CompiledStepper
from proxplan.flightsim.truth import TruthSpec, merge_truth, plan_truth
from proxplan.flightsim.vehicle_params import quad_params
from proxplan.flightsim.wrench import fill_horizon, horizon_states, predicted_wrench, wrench_on
from proxplan.physics import Effect, ModelOptions, Vehicle
from proxplan.planfile import Plan, VehicleTrajectory, read_plan

__all__ = ["CONTROLLERS", "simulate_plan"]


@dataclass(frozen=True)
class _Flight:
    """Everything the flight loop needs, fixed before it starts. Times: ``t_grid_s`` (K,) plan time
    of every physics step, s; per vehicle (V) in ``names`` order."""

    plan: Plan
    names: list[str]
    trajs: list[VehicleTrajectory]
    vehicles: list[Vehicle]  # the vehicles flown (the plan's, or the ones given instead)
    params: list[dict]  # RotorPy quad_params of each
    effects: tuple[Effect, ...]
    model_options: ModelOptions
    truth: TruthSpec
    t_grid_s: np.ndarray
    log_every: int  # physics steps per log sample
    refs: FlightReferences
    predicted_force_N: np.ndarray  # (K, V, 3) the plan's predicted disturbance, world frame
    predicted_torque_Nm: np.ndarray  # (K, V, 3) world axes
    extra_force_N: np.ndarray  # (K, V, 3) residual force beyond the model (perturbation), N, world
    extra_torque_Nm: np.ndarray  # (K, V, 3) residual torque beyond the model (perturbation), N m, world axes
    start_offset_m: np.ndarray  # (V, 3)
    notes: tuple[str, ...]
    wrench_of_state: Callable | None = None  # Perturbation.wrench_of_state: into extra_force_N / extra_torque_Nm

    @property
    def t0_s(self) -> float:
        return float(self.t_grid_s[0])


def simulate_plan(
    plan: Plan | str | Path,
    *,
    options: SimulationOptions | None = None,
    truth: TruthSpec | None = None,
    truth_effects: Sequence[Effect] = (),
    vehicles: Mapping[str, Vehicle] | None = None,
    perturbation: Perturbation | None = None,
    progress: bool = False,
    tube_growth=None,
    **option_values,
) -> SimulationResult:
    """Fly ``plan`` (a :class:`proxplan.planfile.plan.Plan` or a plan.json path) closed loop.

    ``options`` (default :class:`SimulationOptions`), with any of its fields given as keywords
    instead (``seed=3, settle_s=0.2``; a keyword names a field or is a TypeError). ``truth`` (or
    just ``truth_effects``) adds effects beyond the model; without ``truth`` the world is
    :func:`proxplan.flightsim.truth.plan_truth` (the plan's field form and effects) plus
    ``truth_effects`` (give ``truth=merge_truth(plan_truth(plan), extra)`` to add to the plan's
    effects); ``vehicles`` maps type names to the vehicles actually flown instead of the plan's own
    parameters (a heavier or weaker airframe than planned: the set-points stay those of the plan's
    vehicle, as an export computed them). ``perturbation`` adds start, timing, residual-force and
    estimate errors. ``tube_growth``: the plan's :class:`proxplan.verify.TubeGrowth` when known (else
    computed, and cached per plan object), which the records carry as the prediction.

    Controller: ``options.controller`` (module docstring; the Mellinger law has its own integrators).
    ``position_integral_rate_ps`` > 0 adds integral action on the position error, as the seed's
    cascaded PID (S0 IV-D): with diagonal gains k_p e + k_i int(e) dt = k_p (e + (k_i / k_p) int(e) dt),
    so the integral enters as a shift of the position set-point; the integrated error is clipped to
    +-``position_integral_limit_ms`` (anti-windup).
    """
    if isinstance(plan, (str, Path)):
        plan = read_plan(plan)
    if truth is None:  # the world the plan was made for (its calibrated effects too) + truth_effects
        truth = merge_truth(plan_truth(plan), TruthSpec(effects=tuple(truth_effects)), extra_form=False)
    elif truth_effects:
        truth = TruthSpec(tuple(truth.effects) + tuple(truth_effects), truth.wind_mps, truth.field_form)
    options = dataclasses.replace(options or SimulationOptions(), **option_values)
    flight = _prepare(plan, truth, vehicles or {}, options, perturbation or Perturbation())
    wall_start = time.perf_counter()
    log, sat_steps, status, detail = _fly(flight, options, progress)
    return _result(flight, options, log, sat_steps, status, detail, time.perf_counter() - wall_start, tube_growth)


def _prepare(
    plan: Plan, truth: TruthSpec, vehicles: Mapping[str, Vehicle], options: SimulationOptions, pert: Perturbation
) -> _Flight:
    dt = options.physics_dt_s
    log_every = int(round(options.log_dt_s / dt))
    if dt <= 0 or log_every < 1 or abs(log_every * dt - options.log_dt_s) > 1e-9:
        raise UserError(f"log_dt_s ({options.log_dt_s} s) must be a positive multiple of physics_dt_s ({dt} s)")
    names = list(plan.vehicles)
    trajs = [plan.vehicles[n] for n in names]
    vehs = [vehicles.get(t.type_name, t.vehicle) for t in trajs]
    t0 = min(float(t.t_s[0]) for t in trajs)
    t_end = max(float(t.t_s[-1]) for t in trajs)
    n_steps = int(round((t_end - t0 + options.settle_s) / dt / log_every)) * log_every + 1
    t_grid = t0 + dt * np.arange(n_steps)
    refs = flight_references(names, trajs, t_grid, options, pert)
    shifts = np.array([float(pert.time_offset_s.get(n, 0.0)) for n in names])
    # what the plan predicted, on each vehicle's (possibly late) plan time
    pred_f, pred_t, ff_note = predicted_wrench(plan, names, t_grid[:, None] - shifts[None, :])
    extra_f = np.zeros((n_steps, len(names), 3))
    for vi, n in enumerate(names):
        if n in pert.force_N:
            extra_f[:, vi] = pert.force_N[n](t_grid - t0)
    start = np.array([pert.start_offset_m.get(n, (0.0, 0.0, 0.0)) for n in names], dtype=float)
    notes: tuple[str, ...] = (ff_note,) if options.feedforward and ff_note else ()
    late = [e.name for e in truth.effects if e.lag_s > 0.0]
    if late:  # each step's wrench is evaluated on that step's state alone (no history to delay it along)
        notes += (f"the simulator applies {', '.join(late)} at once: a delay (lag_s) is not simulated",)
    return _Flight(
        plan, names, trajs, vehs, [quad_params(v) for v in vehs], tuple(truth.effects),
        ModelOptions(field_form=truth.field_form), truth, t_grid, log_every, refs, pred_f, pred_t, extra_f,
        np.zeros_like(extra_f), start, notes, pert.wrench_of_state,
    )  # fmt: skip


_STEPPER_CACHE: dict = {}
_GROWTH_CACHE: dict = {}


def _tube_growth(plan: Plan):
    """The plan's predicted tube growth (:func:`proxplan.verify.predicted_tube_growth`), cached per
    plan object (certify flies one plan many times)."""
    from proxplan.verify import predicted_tube_growth

    key = id(plan)
    hit = _GROWTH_CACHE.get(key)
    if hit is None or hit[0] is not plan:
        if len(_GROWTH_CACHE) > 8:
            _GROWTH_CACHE.clear()
        hit = _GROWTH_CACHE[key] = (plan, predicted_tube_growth(plan))
    return hit[1]


def _stepper(params: list[dict], dt_s: float, wind_mps, gains: list) -> CompiledStepper:
    """A compiled stepper for these vehicles (cached: building one takes ~0.1 s per vehicle)."""
    key = (repr(params), float(dt_s), tuple(float(w) for w in wind_mps), repr(gains))
    if key not in _STEPPER_CACHE:
        if len(_STEPPER_CACHE) > 16:
            _STEPPER_CACHE.clear()
        _STEPPER_CACHE[key] = CompiledStepper(params, dt_s, wind_mps=wind_mps, controllers=gains)
    return _STEPPER_CACHE[key]


def _initial_stepper(flight: _Flight, options: SimulationOptions) -> CompiledStepper:
    """The cached stepper reset for this flight: fresh controller memory and no feed-forward left
    from an earlier flight; every vehicle at its plan start (plus its start offset) and velocity,
    level, rotors at hover speed, rejecting from t0 whatever acts on it."""
    gains = [controller_gains(v) if options.controller == "mellinger" else None for v in flight.vehicles]
    stepper = _stepper(flight.params, options.physics_dt_s, flight.truth.wind_mps, gains)
    stepper.ctrl_mem[:] = 0.0
    stepper.ff_force_N[:] = 0.0
    stepper.ff_torque_Nm[:] = 0.0
    s = stepper.state
    s[:] = 0.0
    s[:, 0:3] = flight.refs.plan_position_m[0] + flight.start_offset_m
    s[:, 3:6] = flight.refs.plan_velocity_mps[0]
    s[:, 9] = 1.0  # identity attitude, [x, y, z, w]
    hover = [np.sqrt(v.hover_thrust_per_rotor_N / p["k_eta"]) for v, p in zip(flight.vehicles, flight.params)]
    s[:, 13:17] = np.array(hover)[:, None]
    return stepper


def _add_wrench_of_state(
    flight: _Flight, wrench_of_state: Callable, k: int, tau: np.ndarray, s: np.ndarray, acc: np.ndarray
) -> None:
    """Add ``wrench_of_state`` (:attr:`Perturbation.wrench_of_state`) over the horizon that starts at physics step
    ``k`` (offsets ``tau`` (K,), s) to ``flight.extra_force_N`` and ``flight.extra_torque_Nm``, on the states
    predicted from state ``s`` (V, 17) and the acceleration estimate ``acc`` (V, 3) as
    :func:`proxplan.flightsim.wrench.fill_horizon` predicts them."""
    n = min(len(tau), len(flight.t_grid_s) - k)
    tau = tau[:n]
    pos, vel = horizon_states(s[:, 0:3], s[:, 3:6], acc, tau)
    t = flight.t_grid_s[k : k + n] - flight.t0_s
    force_N, torque_Nm = wrench_of_state(t, pos, vel, np.repeat(acc[None], n, axis=0))
    flight.extra_force_N[k : k + n] += force_N
    flight.extra_torque_Nm[k : k + n] += torque_Nm


def _fly(flight: _Flight, options: SimulationOptions, progress: bool):
    """The flight loop: (log, saturated physics steps per vehicle (V,), status, status detail)."""
    dt = options.physics_dt_s
    n_steps, n_veh = flight.t_grid_s.size, len(flight.names)
    horizon = max(1, int(options.wrench_horizon_steps))
    log = FlightLog((n_steps - 1) // flight.log_every + 1, n_veh)
    stepper = _initial_stepper(flight, options)
    s = stepper.state
    k_eta = np.array([p["k_eta"] for p in flight.params])[:, None]
    setpoints, refs = flight.refs.setpoints, flight.refs
    acc_est = np.zeros((n_veh, 3))
    buf_f, buf_t = np.zeros((n_veh, horizon, 3)), np.zeros((n_veh, horizon, 3))
    tau = dt * np.arange(horizon)
    integral_ms = np.zeros((n_veh, 3))  # integrated position error, m s
    ki_rate = float(options.position_integral_rate_ps)
    sat_steps = np.zeros(n_veh)
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=n_steps, desc="simulate", unit="step", unit_scale=True, leave=False)
    try:
        for k in range(n_steps):
            j = k % horizon
            if j == 0:
                fill_horizon(buf_f, buf_t, s[:, 0:3], s[:, 3:6], acc_est, tau, flight.vehicles, flight.effects,
                             flight.model_options, options.ground_z_m)  # fmt: skip
                if flight.wrench_of_state is not None:
                    _add_wrench_of_state(flight, flight.wrench_of_state, k, tau, s, acc_est)
            stepper.ref[:] = setpoints[k]
            if ki_rate > 0.0:
                integral_ms += (s[:, 0:3] - setpoints[k][:, 0:3]) * dt
                np.clip(integral_ms, -options.position_integral_limit_ms, options.position_integral_limit_ms,
                        out=integral_ms)  # fmt: skip
                stepper.ref[:, 0:3] -= ki_rate * integral_ms
            stepper.ext_force_N[:] = buf_f[:, j] + flight.extra_force_N[k]
            stepper.ext_torque_Nm[:] = buf_t[:, j] + flight.extra_torque_Nm[k]
            if options.feedforward:
                stepper.ff_force_N[:] = flight.predicted_force_N[k]
                stepper.ff_torque_Nm[:] = flight.predicted_torque_Nm[k]
            stepper.step()
            sat_steps += stepper.saturated
            if k % flight.log_every == 0:
                i = k // flight.log_every
                log.put(
                    i, position_m=s[:, 0:3], velocity_mps=s[:, 3:6], acceleration_mps2=stepper.accel_mps2,
                    q_xyzw=s[:, 6:10], w_body_radps=s[:, 10:13],
                    ref_position_m=refs.plan_position_m[k], ref_velocity_mps=refs.plan_velocity_mps[k],
                    setpoint_position_m=setpoints[k][:, 0:3],
                    motor_thrust_N=k_eta * s[:, 13:17] ** 2, cmd_motor_thrust_N=stepper.cmd_thrust_N,
                    cmd_thrust_N=stepper.ctbm[:, 0], cmd_moment_Nm=stepper.ctbm[:, 1:4],
                    applied_force_N=buf_f[:, j] + flight.extra_force_N[k],
                    applied_torque_Nm=buf_t[:, j] + flight.extra_torque_Nm[k],
                )  # fmt: skip
                log.saturated[i] = stepper.saturated > 0.5
            acc_est = (stepper.next_state[:, 3:6] - s[:, 3:6]) / dt
            stepper.advance()
            if not np.all(np.isfinite(s)):
                lost = [flight.names[v] for v in range(n_veh) if not np.all(np.isfinite(s[v]))]
                t_lost = flight.t_grid_s[k] - flight.t0_s
                log.truncate(k // flight.log_every + 1)  # rows logged up to step k hold finite states
                detail = f"{', '.join(lost)} lost control at t = {t_lost:.3f} s (state not finite)"
                return log, sat_steps, SimulationStatus.DIVERGED, detail
            if bar is not None and k % 500 == 0:
                bar.update(min(500, n_steps - k))
    finally:
        if bar is not None:
            bar.close()
    return log, sat_steps, SimulationStatus.COMPLETE, ""


def _result(
    flight: _Flight,
    options: SimulationOptions,
    log: FlightLog,
    sat_steps: np.ndarray,
    status: SimulationStatus,
    detail: str,
    wall_s: float,
    tube_growth=None,
) -> SimulationResult:
    """IMU samples and the base-model wrench added to the log, records and notes assembled."""
    arr = log.arrays
    n_logged = arr["position_m"].shape[0]
    every = flight.log_every
    rng = np.random.default_rng(options.seed)
    for vi in range(len(flight.names)):
        arr["accel_meas_body_mps2"][:, vi], arr["gyro_meas_radps"][:, vi] = imu_samples(
            arr["q_xyzw"][:, vi],
            arr["w_body_radps"][:, vi],
            arr["acceleration_mps2"][:, vi],
            options=options.imu,
            rng=rng,
            with_noise=options.imu_noise,
        )
    if flight.effects:  # base-model part of the applied wrench at the logged states
        for vi in range(len(flight.names)):
            arr["model_force_N"][:, vi], arr["model_torque_Nm"][:, vi] = wrench_on(
                vi,
                arr["position_m"],
                arr["velocity_mps"][:, vi],
                flight.vehicles,
                (),
                flight.model_options,
                options.ground_z_m,
            )
    else:
        arr["model_force_N"][:] = arr["applied_force_N"] - flight.extra_force_N[::every][:n_logged]
        arr["model_torque_Nm"][:] = arr["applied_torque_Nm"] - flight.extra_torque_Nm[::every][:n_logged]
    t_log = (flight.t_grid_s[::every] - flight.t0_s)[:n_logged]
    growth = tube_growth if tube_growth is not None else _tube_growth(flight.plan)
    records = {
        name: log.record(
            vi, name, flight.trajs[vi].type_name, flight.vehicles[vi], t_log,
            predicted_force_N=flight.predicted_force_N[::every][:n_logged, vi],
            predicted_torque_Nm=flight.predicted_torque_Nm[::every][:n_logged, vi],
            predicted_deflection_m=growth.at(name, t_log), tube_m=growth.tube_m,
        )
        for vi, name in enumerate(flight.names)
    }  # fmt: skip
    notes = list(flight.notes)
    for name, record in records.items():
        low = float(record.position_m[:, 2].min()) if n_logged else options.ground_z_m
        if low < options.ground_z_m:
            notes.append(f"{name} went below the ground plane (min z = {low:.3f} m): ground contact is not modelled")
    plan_end = max(float(t.t_s[-1]) for t in flight.trajs)
    return SimulationResult(
        scenario=str(flight.plan.scenario),
        options=options,
        truth=flight.truth,
        plan_duration_s=plan_end - flight.t0_s,
        records=records,
        saturation_time_s={n: float(sat_steps[i] * options.physics_dt_s) for i, n in enumerate(flight.names)},
        wall_time_s=wall_s,
        sim_time_s=float(t_log[-1]) if n_logged else 0.0,
        notes=notes,
        status=status,
        status_detail=detail,
        max_lead_m=dict(flight.refs.max_lead_m),
    )
