"""Each vehicle's predicted deviation from its own plan when it flies it (the reference the export
uploads, with the default controller), on the verifier's grid: the plan's and the reference's
samples for :func:`proxplan.physics.tracking_response`. World frame; m, s."""

from __future__ import annotations

import dataclasses

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

TAIL_SETTLE_S = 2.0
"""The tail is run this long past the reference's end, s, before the loop's modes bound the rest:
the attitude and motor modes (< 0.3 s) have died out by then, so the modal bound (a sum of every
mode's largest share) is not taken in the middle of a fast transient."""


def reference_samples(
    tr: VehicleTrajectory, t_s: np.ndarray, samples: tuple[np.ndarray, ...] | None = None
) -> tuple[ReferenceSamples, ReferenceSamples]:
    """The plan's and its compensated reference's samples on ``t_s`` (K,), s (uniform from the
    plan's start), and over the reference's settle tail after ``t_s``'s end on a grid of
    :data:`proxplan.physics.tracking_loop.TAIL_STEP_S` (from ``t_s``'s last time); ``samples``:
    ``tr.sample(t_s)`` if already taken."""
    t = np.asarray(t_s, dtype=float)
    rested = _at_rest_at_the_end(tr)
    if rested is not tr:  # another trajectory: its own samples
        tr, samples = rested, None
    ref = compensated_reference(tr).trajectory
    end = float(ref.t_s[-1]) + SETPOINT_DELAY_S + TAIL_SETTLE_S
    n_tail = max(1, int(np.ceil((end - float(t[-1])) / TAIL_STEP_S)))
    tail = float(t[-1]) + TAIL_STEP_S * np.arange(n_tail + 1)
    return _samples(tr, ref, t, samples), _samples(tr, ref, tail)


def _at_rest_at_the_end(tr: VehicleTrajectory) -> VehicleTrajectory:
    """``tr`` with its last sample's velocity and acceleration zero: a plan ends at rest (verify
    allows ``REST_SPEED_MPS`` there, e.g. an export read back still creeping by its lead), and the
    compensated reference, which holds the plan's end, would otherwise jump there."""
    if not (np.any(tr.velocity_mps[-1]) or np.any(tr.acceleration_mps2[-1])):
        return tr
    v, a = tr.velocity_mps.copy(), tr.acceleration_mps2.copy()
    v[-1] = a[-1] = 0.0
    return dataclasses.replace(tr, velocity_mps=v, acceleration_mps2=a)


def _samples(
    tr: VehicleTrajectory, ref: VehicleTrajectory, grid: np.ndarray, samples: tuple[np.ndarray, ...] | None = None
) -> ReferenceSamples:
    p, v, a = samples if samples is not None else tr.sample(grid)
    late = grid - SETPOINT_DELAY_S
    rp, rv, ra = ref.sample(late)
    h = 1.0 / FIRMWARE_SETPOINT_RATE_HZ  # the firmware's difference of held set-points, within the reference
    step = np.diff(grid)
    if step.size and np.allclose(step, h, rtol=0.0, atol=1e-9 * h):
        # windows that tile time share their edges (one array): a jump of the reference's jerk is
        # counted in exactly one window, wherever it falls against the grid (computed apart, a jump
        # on an edge could be counted twice or not at all, by rounding: the prediction then changed
        # with the plan's start time, 0.7 -> 2.1 cm for one 0.5 m move at 2 m/s, 4 m/s^2, 16 m/s^3)
        edges = np.clip(late[0] - h / 2 + h * np.arange(grid.size + 1), ref.t_s[0], ref.t_s[-1])
        lo, hi = edges[:-1], edges[1:]
        j_edges = ref.jerk_at(edges)
        j_lo, j_hi = j_edges[:-1], j_edges[1:]
    else:
        lo = np.clip(late - h / 2, ref.t_s[0], ref.t_s[-1])
        hi = np.clip(late + h / 2, ref.t_s[0], ref.t_s[-1])
        j_lo, j_hi = ref.jerk_at(lo), ref.jerk_at(hi)
    width = np.maximum(hi - lo, 1e-12)[:, None]
    snap = np.where(hi[:, None] > lo[:, None], (j_hi - j_lo) / width, 0.0)
    return ReferenceSamples(grid, p, v, a, rp, rv, ra, ref.jerk_at(late), snap)


def tracking_along_plan(
    tr: VehicleTrajectory, t_s: np.ndarray, *, samples: tuple[np.ndarray, ...] | None = None
) -> TrackingResponse:
    """The predicted deviation of ``tr``'s vehicle from its plan on ``t_s`` (K,), s (uniform, from
    the plan's start), and the largest after the plan's end (:func:`proxplan.physics.tracking_response`);
    ``samples``: ``tr.sample(t_s)`` if already taken."""
    return tracking_response(tr.vehicle, *reference_samples(tr, t_s, samples))
