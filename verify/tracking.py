"""Each vehicle's predicted deviation from its own plan when it flies it (the reference the export
uploads, with the default controller), on the verifier's grid: the plan's and the reference's
samples for :func:`proxplan.physics.tracking_response`. World frame; m, s."""

from __future__ import annotations

import numpy as np

from proxplan.physics import (
    FIRMWARE_SETPOINT_RATE_HZ,
    SETPOINT_DELAY_S,
    ReferenceSamples,
    TrackingResponse,
    tracking_response,
)
from proxplan.planfile import VehicleTrajectory, compensated_reference


def reference_samples(tr: VehicleTrajectory, t_s: np.ndarray) -> tuple[ReferenceSamples, int]:
    """(samples on ``t_s`` (K,), s, uniform from the plan's start, continued over the compensated
    reference's settle tail; the number K of the plan's own samples)."""
    t = np.asarray(t_s, dtype=float)
    ref = compensated_reference(tr).trajectory
    step = float(t[1] - t[0]) if t.size >= 2 else 0.01
    n_tail = max(0, int(np.ceil((float(ref.t_s[-1]) + SETPOINT_DELAY_S - float(t[-1])) / step)))
    grid = np.concatenate([t, t[-1] + step * np.arange(1, n_tail + 1)])
    p, v, a = tr.sample(grid)
    late = grid - SETPOINT_DELAY_S
    rp, rv, ra = ref.sample(late)
    h = 1.0 / FIRMWARE_SETPOINT_RATE_HZ  # the firmware's difference of held set-points
    snap = (ref.jerk_at(late + h / 2) - ref.jerk_at(late - h / 2)) / h
    return ReferenceSamples(grid, p, v, a, rp, rv, ra, ref.jerk_at(late), snap), t.size


def tracking_along_plan(tr: VehicleTrajectory, t_s: np.ndarray) -> TrackingResponse:
    """The predicted deviation of ``tr``'s vehicle from its plan on ``t_s`` (K,), s (uniform, from
    the plan's start), and the largest after the plan's end (:func:`proxplan.physics.tracking_response`)."""
    samples, n_plan = reference_samples(tr, t_s)
    return tracking_response(tr.vehicle, samples, n_plan)
