"""The reference a vehicle is given so that it flies its plan, and the path a given reference is
predicted to fly: :mod:`proxplan.physics.closed_loop` on a :class:`VehicleTrajectory`.

* :func:`compensated_reference`: the plan (averaged over the motor time constant) + its lead delta
  (with the settle tail after the plan's end), what ``proxplan export`` uploads and ``simulate`` /
  ``track-limits`` / ``certify`` fly by default. Sampled on a grid :data:`LEAD_SUBSTEPS` times
  finer than the plan's (the lead has a fast mode, the firmware's rate-error derivative), from one
  plan step before the plan to the end of the tail, position, velocity and acceleration exact at
  the samples, quintic Hermite in between as every plan.
* :func:`predicted_path`: where a vehicle flying a reference (an upload's polynomials) will be:
  reference - its predicted lag. For the compensated reference this is the plan again (exactly,
  in the linear model); for an uncompensated upload it is the plan lagging by the rotor drag.

World frame, m, m/s, m/s^2, s.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import uniform_filter1d

from proxplan.physics import Vehicle, drag_lead, reference_error
from proxplan.planfile.plan import VehicleTrajectory

LEAD_SUBSTEPS = 5
"""The compensated reference is sampled this many times finer than its plan, -."""


@dataclass(frozen=True)
class CompensatedReference:
    """A vehicle's compensated reference: ``trajectory`` (plan + lead, over the plan and its settle
    tail) of the ``plan``, the plan's end time ``plan_end_s`` (s), the largest lead ``max_lead_m``
    (m, over the plan and the tail) and the lead left when the tail ends ``residual_m`` (m); the
    two leads are computed when first asked for (the tracking prediction, which builds a reference
    per vehicle and per check, never asks)."""

    trajectory: VehicleTrajectory
    plan_end_s: float
    plan: VehicleTrajectory

    @functools.cached_property
    def _lead_norm_m(self) -> np.ndarray:
        return np.linalg.norm(self.trajectory.position_m - self.plan.sample(self.trajectory.t_s)[0], axis=1)

    @property
    def max_lead_m(self) -> float:
        return float(self._lead_norm_m.max())

    @property
    def residual_m(self) -> float:
        return float(self._lead_norm_m[-1])

    @property
    def tail_s(self) -> float:
        """Duration of the settle tail after the plan's end, s."""
        return float(self.trajectory.t_s[-1]) - self.plan_end_s


def smoothed_plan(
    tr: VehicleTrajectory, t_s: np.ndarray, window_s: float, axes: list[int] | None = None
) -> tuple[np.ndarray, ...]:
    """(position m, velocity m/s, acceleration m/s^2, jerk m/s^3), each (K, 3), of the plan ``tr``
    at the uniform times ``t_s`` (K,), s (at rest outside the plan), its ``axes`` (default: the
    vertical one, whose thrust the motor lag delays) averaged over a centred window of ``window_s`` (s). A moving average keeps every speed, acceleration and jerk within the plan's
    largest (a positive kernel of unit mass), moves positions by only ~a w^2 / 24, and makes the
    plan's jerk continuous, so its motor-lag lead stays C2."""
    p, v, a = tr.sample(t_s)
    j = tr.jerk_at(t_s)
    axes = [2] if axes is None else axes
    if t_s.size < 2 or window_s <= 0.0:
        return p, v, a, j
    size = max(1, int(round(window_s / float(t_s[1] - t_s[0]))) // 2 * 2 + 1)  # odd, centred
    out = []
    for x in (p, v, a, j):
        x = x.copy()
        x[:, axes] = uniform_filter1d(x[:, axes], size=size, axis=0, mode="nearest")
        out.append(x)
    return tuple(out)


def compensated_reference(tr: VehicleTrajectory, *, tail: bool = True) -> CompensatedReference:
    """The plan ``tr``, its vertical axis averaged over the vehicle's motor time constant
    (:func:`smoothed_plan`), + its drag lead (module docstring), from one plan step before the plan (where the averaged plan
    starts to move) to its end, and without ``tail`` ends there."""
    step = float(tr.t_s[1] - tr.t_s[0]) if tr.t_s.size >= 2 else 0.05
    window = min(tr.vehicle.motor_time_constant_s, 2.0 * step)  # the averaged plan moves one step early at most
    t0, t1 = float(tr.t_s[0]) - step, float(tr.t_s[-1]) + step
    fine_step = step / LEAD_SUBSTEPS
    fine = t0 + fine_step * np.arange(int(round((t1 - t0) / fine_step)) + 1)
    p, v, a, j = smoothed_plan(tr, fine, window)
    lead = drag_lead(fine, v, a, j, tr.vehicle, tail=tail, end_multiple=LEAD_SUBSTEPS)
    n = fine.size
    rest = np.clip(np.arange(lead.t_s.size), 0, n - 1)  # the averaged plan is at rest at its end over the tail
    moving = (np.arange(lead.t_s.size) < n)[:, None]
    traj = VehicleTrajectory(
        tr.name,
        tr.type_name,
        tr.vehicle,
        lead.t_s,
        p[rest] + lead.value,
        np.where(moving, v[rest], 0.0) + lead.rate,
        np.where(moving, a[rest], 0.0) + lead.accel,
    )
    return CompensatedReference(traj, float(tr.t_s[-1]), tr)


def predicted_path(
    t_s: np.ndarray,
    position_m: np.ndarray,
    velocity_mps: np.ndarray,
    acceleration_mps2: np.ndarray,
    jerk_mps3: np.ndarray,
    vehicle: Vehicle,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(position_m, velocity_mps, acceleration_mps2), each (K, 3), of ``vehicle`` flying the
    reference sampled (with its jerk) on the uniform grid ``t_s`` (K,), s: the reference minus its
    predicted lag (:func:`proxplan.physics.reference_error`; start from rest)."""
    err = reference_error(t_s, velocity_mps, acceleration_mps2, jerk_mps3, vehicle)
    return position_m - err.value, velocity_mps - err.rate, acceleration_mps2 - err.accel


def drag_feedforward_mps2(tr: VehicleTrajectory, t_s: np.ndarray) -> np.ndarray:
    """The drag term c v (K, 3), m/s^2, a full-state set-point adds to its acceleration feed-forward
    at plan times ``t_s`` (K,), s, so that a controller with acceleration feed-forward cancels the
    rotor drag the plan meets (c: ``Vehicle.drag_rate_ps``, per axis, 1/s)."""
    return tr.vehicle.drag_rate_ps * tr.sample(t_s)[1]
