"""The set-points each simulated vehicle's controller is given, and the plan it is measured against.

* The plan, sampled at every physics step (late by the vehicle's timing error, if any): tracking
  errors are measured against it.
* The set-points: with ``drag_compensation`` (default) the compensated reference the export uploads
  (:func:`proxplan.planfile.reference.compensated_reference`: plan + drag lead, with its settle tail)
  for the Mellinger law; RotorPy's SE(3) law, which streams full-state set-points, gets the plan
  with the drag term c v added to its acceleration feed-forward (as ``proxplan export --format csv``
  writes it). The Mellinger law evaluates its set-points at ``setpoint_rate_hz`` and holds them (the
  firmware's high-level commander), with the body-rate feed-forward from the reference's jerk.
* Estimate errors of a :class:`~proxplan.flightsim.options.Perturbation` shift the set-points (an
  estimate x + n is flown as the reference x_ref - n).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from proxplan.fileio import UserError
from proxplan.flightsim.mellinger import reference_body_rates
from proxplan.flightsim.options import CONTROLLERS, Perturbation, SimulationOptions
from proxplan.planfile import VehicleTrajectory, compensated_reference, drag_feedforward_mps2


@dataclass(frozen=True)
class FlightReferences:
    """Per physics step k (K) and vehicle (V): the plan's position and velocity (K, V, 3), m and
    m/s, and the set-points (K, V, 12): position m, velocity m/s, acceleration m/s^2 (world frame)
    and body-rate feed-forward rad/s (body frame). ``max_lead_m``: largest distance of the
    position set-point from the plan per vehicle, m."""

    plan_position_m: np.ndarray
    plan_velocity_mps: np.ndarray
    setpoints: np.ndarray
    max_lead_m: dict[str, float] = field(default_factory=dict)


def flight_references(
    names: Sequence[str],
    trajs: Sequence[VehicleTrajectory],
    t_grid_s: np.ndarray,
    options: SimulationOptions,
    perturbation: Perturbation,
) -> FlightReferences:
    """References of ``trajs`` at the physics-step times ``t_grid_s`` (K,), s (module docstring)."""
    if options.controller not in CONTROLLERS:
        raise UserError(f"controller: expected one of {', '.join(CONTROLLERS)}, got {options.controller!r}")
    mellinger = options.controller == "mellinger"
    t0 = float(t_grid_s[0])
    if mellinger:  # the firmware evaluates the trajectory at its set-point rate and holds it
        if options.setpoint_rate_hz <= 0:
            raise UserError(f"setpoint_rate_hz: expected a positive rate, Hz, got {options.setpoint_rate_hz}")
        t_sp = t0 + np.floor((t_grid_s - t0) * options.setpoint_rate_hz + 1e-9) / options.setpoint_rate_hz
    else:
        t_sp = t_grid_s
    k, n = t_grid_s.size, len(trajs)
    plan_x, plan_v = np.zeros((k, n, 3)), np.zeros((k, n, 3))
    sp = np.zeros((k, n, 12))
    leads: dict[str, float] = {}
    for vi, (name, tr) in enumerate(zip(names, trajs)):
        shift = float(perturbation.time_offset_s.get(name, 0.0))
        plan_x[:, vi], plan_v[:, vi], _ = tr.sample(t_grid_s - shift)
        flown = tr
        if options.drag_compensation and mellinger:
            flown = compensated_reference(tr).trajectory
        p, v, a = flown.sample(t_sp - shift)
        if options.drag_compensation and not mellinger:
            a = a + drag_feedforward_mps2(tr, t_sp - shift)
        sp[:, vi, 0:3], sp[:, vi, 3:6], sp[:, vi, 6:9] = p, v, a
        if mellinger and options.rate_feedforward:
            sp[:, vi, 9:12] = reference_body_rates(a, flown.jerk_at(t_sp - shift))
        leads[name] = float(np.linalg.norm(p - tr.sample(t_sp - shift)[0], axis=1).max())
        if name in perturbation.estimate_error_m:
            sp[:, vi, 0:3] -= perturbation.estimate_error_m[name](t_grid_s - t0)
        if name in perturbation.estimate_error_mps:
            sp[:, vi, 3:6] -= perturbation.estimate_error_mps[name](t_grid_s - t0)
    return FlightReferences(plan_x, plan_v, sp, leads)
