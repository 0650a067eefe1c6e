"""Each vehicle's predicted deviation from its own plan when it flies it (the reference the export
uploads, with the default controller), on the verifier's grid: the plan's and the reference's
samples for :func:`proxplan.physics.tracking_response`. World frame; m, s."""

from __future__ import annotations

import numpy as np

from proxplan.physics import (
    FIRMWARE_SETPOINT_RATE_HZ,
    SETPOINT_DELAY_S,
    TAIL_STEP_S,
    ReferenceSamples,
    TrackingResponse,
    tracking_response,
)
from proxplan.planfile import VehicleTrajectory, compensated_reference


def reference_samples(tr: VehicleTrajectory, t_s: np.ndarray) -> tuple[ReferenceSamples, ReferenceSamples]:
    """The plan's and its compensated reference's samples on ``t_s`` (K,), s (uniform from the
    plan's start), and over the reference's settle tail after ``t_s``'s end on a grid of
    :data:`proxplan.physics.tracking_loop.TAIL_STEP_S` (from ``t_s``'s last time)."""
    t = np.asarray(t_s, dtype=float)
    ref = compensated_reference(tr).trajectory
    n_tail = max(1, int(np.ceil((float(ref.t_s[-1]) + SETPOINT_DELAY_S - float(t[-1])) / TAIL_STEP_S)))
    return _samples(tr, ref, t), _samples(tr, ref, float(t[-1]) + TAIL_STEP_S * np.arange(n_tail + 1))


def _samples(tr: VehicleTrajectory, ref: VehicleTrajectory, grid: np.ndarray) -> ReferenceSamples:
    p, v, a = tr.sample(grid)
    late = grid - SETPOINT_DELAY_S
    rp, rv, ra = ref.sample(late)
    h = 1.0 / FIRMWARE_SETPOINT_RATE_HZ  # the firmware's difference of held set-points
    snap = (ref.jerk_at(late + h / 2) - ref.jerk_at(late - h / 2)) / h
    return ReferenceSamples(grid, p, v, a, rp, rv, ra, ref.jerk_at(late), snap)


def tracking_along_plan(tr: VehicleTrajectory, t_s: np.ndarray) -> TrackingResponse:
    """The predicted deviation of ``tr``'s vehicle from its plan on ``t_s`` (K,), s (uniform, from
    the plan's start), and the largest after the plan's end (:func:`proxplan.physics.tracking_response`)."""
    return tracking_response(tr.vehicle, *reference_samples(tr, t_s))
