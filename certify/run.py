"""One certification run: draw (seed, index), fly the plan closed loop, reduce to a small dict.

Per vehicle (world frame, SI): peak authority usage of the disturbance actually applied (model with
the drawn parameters + truth effects + the drawn residual, DESIGN.md s. 3), peak and final tracking
error against the plan's own reference (timing errors count as tracking error), smallest separation
to any other vehicle at times where the plan itself keeps the required separation (dock pairs:
plus :data:`DOCK_APPROACH_BAND_M`).

Run outcomes: ``authority_exceeded`` (some vehicle's peak usage > the scenario's
``authority_fraction``, or the flight diverged), ``separation_violated`` (two vehicles closer than
max(min_separation_m, sum of body radii) where the plan keeps that distance, or diverged),
``goal_missed`` (a vehicle ends farther than ``goal_tolerance_m`` from its planned final position,
or diverged), ``left_tube`` (a vehicle flew farther from the plan than the tube the verifier granted
plus its predicted growth (its tracking error along its reference and in the jets,
``proxplan.verify.predicted_tube_growth``), the hold after the
end included; or diverged: the promise ``verify`` makes).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from proxplan.certify.draws import NoiseSpec, RunDraw, Spreads, draw_run
from proxplan.flightsim import (
    Perturbation,
    SimulationOptions,
    SimulationStatus,
    TruthSpec,
    predicted_deflection_m,
    record_tube_m,
    simulate_plan,
)
from proxplan.identify import apply_vehicle_parameters
from proxplan.physics import Effect, Vehicle, authority_usage
from proxplan.planfile import Plan

DEFAULT_GOAL_TOLERANCE_M = 0.10
"""Largest final position error (after the settle time) that still counts as reaching the goal, m:
twice the verifier's planning tolerance (proxplan.verify.GOAL_TOLERANCE_M = 0.05 m), since a flown vehicle
under a steady residual keeps a steady error with RotorPy's PD law."""

DOCK_APPROACH_BAND_M = 0.10
"""A pair the plan itself brings closer than the required separation (a dock) is checked only where
the plan keeps the separation plus this band, m: on the final approach the flown distance follows
the plan's down to the dock, and a few cm of lag there is the dock, not a violation."""


@dataclass(frozen=True)
class CertifySetup:
    """Everything a run needs besides its index (sent once to every worker)."""

    plan: Plan
    seed: int
    authority_limit: float  # scenario's authority_fraction, -
    min_separation_m: float  # scenario's min_separation_m, m
    goal_tolerance_m: float = DEFAULT_GOAL_TOLERANCE_M
    truth: TruthSpec = TruthSpec()
    vehicles: Mapping[str, Vehicle] = field(default_factory=dict)  # flown instead of the plan's types
    effect_spreads: Mapping[str, float] = field(default_factory=dict)  # "effect.param" -> std
    spreads: Spreads = Spreads()
    noise: NoiseSpec = NoiseSpec()
    options: SimulationOptions = SimulationOptions(imu_noise=False)
    tube_growth: Any = None  # the plan's proxplan.verify.TubeGrowth (certify_plan fills it once)

    def flown_types(self) -> dict[str, tuple[str, Vehicle]]:
        """Vehicle name -> (type name, the vehicle flown before drawing), in plan order."""
        return {n: (t.type_name, self.vehicles.get(t.type_name, t.vehicle)) for n, t in self.plan.vehicles.items()}


def _drawn_effects(setup: CertifySetup, rng_draw: RunDraw) -> tuple[Effect, ...]:
    """Truth effects with parameters drawn from ``effect_spreads`` (``effect.param`` keys)."""
    if not setup.effect_spreads:
        return tuple(setup.truth.effects)
    from proxplan.certify.draws import run_rng

    rng = run_rng(rng_draw.sim_seed, 1)  # a separate stream: the other draws stay as they are
    out = []
    for e in setup.truth.effects:
        params = dict(e.full_params())
        for key in sorted(params):
            std = setup.effect_spreads.get(f"{e.name}.{key}")
            if std:
                params[key] = float(params[key] + std * rng.standard_normal())
        out.append(Effect(e.name, params))
    return tuple(out)


def fly_run(setup: CertifySetup, index: int, *, keep_result: bool = False) -> dict[str, Any]:
    """Fly run ``index``: a JSON-able dict (and the SimulationResult under "_result" when
    ``keep_result``)."""
    plan = setup.plan
    flown = setup.flown_types()
    duration = float(plan.makespan_s) + setup.options.settle_s + 1.0
    draw = draw_run(setup.seed, index, flown, duration, spreads=setup.spreads, noise=setup.noise)
    vehicles = {tn: apply_vehicle_parameters(veh, **draw.parameters[tn]) for tn, veh in (v for v in flown.values())}
    truth = TruthSpec(_drawn_effects(setup, draw), setup.truth.wind_mps, setup.truth.field_form)
    pert = Perturbation(
        start_offset_m=draw.start_offset_m,
        time_offset_s=draw.time_offset_s,
        force_N=draw.residual_force_N,
        estimate_error_m=draw.estimate_error_m,
        estimate_error_mps=draw.estimate_error_mps,
    )
    options = replace(setup.options, seed=draw.sim_seed)
    result = simulate_plan(
        plan, truth=truth, vehicles=vehicles, options=options, perturbation=pert, tube_growth=setup.tube_growth
    )
    out = summarise(setup, result, draw)
    if keep_result:
        out["_result"] = result
    return out


def summarise(setup: CertifySetup, result, draw: RunDraw) -> dict[str, Any]:
    """The small per-run dict of :func:`fly_run` from a SimulationResult."""
    plan = setup.plan
    diverged = result.status is not SimulationStatus.COMPLETE
    names = list(result.records)
    t0 = float(min(t.t_s[0] for t in plan.vehicles.values()))
    per_vehicle: dict[str, dict[str, float]] = {}
    plan_pos = {}
    for name in names:
        rec = result.records[name]
        ref = plan.vehicles[name].sample(rec.t_s + t0)[0]
        plan_pos[name] = ref
        err = np.linalg.norm(rec.position_m - ref, axis=1)
        usage = authority_usage(rec.vehicle, rec.applied_force_N, rec.applied_torque_Nm)
        beyond = err - record_tube_m(rec) - predicted_deflection_m(rec)  # -inf where nothing bounds it
        per_vehicle[name] = {
            "peak_authority_usage": float(np.max(usage)) if usage.size else float("inf"),
            "tube_excess_m": float(np.max(beyond)) if beyond.size else float("inf"),
            "max_tracking_error_m": float(err.max()) if err.size else float("inf"),
            "final_error_m": float(err[-1]) if err.size else float("inf"),
            "min_separation_m": float("inf"),
        }
    sep_ok = True
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            ra, rb = result.records[a], result.records[b]
            need = max(setup.min_separation_m, ra.vehicle.body_radius_m + rb.vehicle.body_radius_m)
            d = np.linalg.norm(ra.position_m - rb.position_m, axis=1)
            d_plan = np.linalg.norm(plan_pos[a] - plan_pos[b], axis=1)
            band = DOCK_APPROACH_BAND_M if d_plan.min() < need - 1e-6 else 0.0  # a dock pair
            planned = d_plan >= need + band - 1e-6
            if planned.any():
                closest = float(d[planned].min())
                for n in (a, b):
                    per_vehicle[n]["min_separation_m"] = min(per_vehicle[n]["min_separation_m"], closest)
                sep_ok &= closest >= need
    for v in per_vehicle.values():  # JSON has no infinity: no pair to separate, or nothing flown
        for key, value in v.items():
            if not np.isfinite(value):
                v[key] = None  # type: ignore[assignment]
    authority = diverged or any(
        (v["peak_authority_usage"] or 0.0) > setup.authority_limit for v in per_vehicle.values()
    )
    goal = diverged or any((v["final_error_m"] or 0.0) > setup.goal_tolerance_m for v in per_vehicle.values())
    left = diverged or any(v["tube_excess_m"] is None or v["tube_excess_m"] > 0.0 for v in per_vehicle.values())
    return {
        "index": draw.index,
        "seed": [draw.seed, draw.index],
        "status": result.status.value,
        "authority_exceeded": bool(authority),
        "separation_violated": bool(diverged or not sep_ok),
        "goal_missed": bool(goal),
        "left_tube": bool(left),
        "max_tracking_error_m": max((v["max_tracking_error_m"] or 0.0) for v in per_vehicle.values()),
        "peak_authority_usage": max((v["peak_authority_usage"] or 0.0) for v in per_vehicle.values()),
        "per_vehicle": per_vehicle,
        "parameters": draw.parameters,
        "time_offset_s": draw.time_offset_s,
    }


def fly_runs_locally(setup: CertifySetup, indices: Sequence[int]) -> list[dict[str, Any]]:
    """Runs in this process, in order (for tests and single re-flights)."""
    return [fly_run(setup, k) for k in indices]
