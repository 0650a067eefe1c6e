"""How far a vehicle is predicted to be off its own plan when it flies it, from the same linearised
closed loop as in a jet (:mod:`proxplan.physics.hover_loop`, no jet), driven by what the loops
cannot follow instantly: the reference's changes of acceleration (jerk, snap) against the
airframe's inertia and the motors' lag, the set-point hold, and what is left of the drag's lead.

**Derivation.** The vehicle flies the reference r (the plan + its drag lead, what the export
uploads: :func:`proxplan.planfile.compensated_reference`) with the Mellinger law: force feed-forward
m r'', body-rate feed-forward w_ref = (-r'''_y, r'''_x, 0) / g (differential flatness, linearised
at hover) and its derivative through the rate-error derivative k_dw. In the loop's states
(:data:`proxplan.physics.hover_loop.STATE_NAMES`) taken as deviations from the plan p (position and
velocity; attitude, rates, motor outputs and integrators as they are, about a level hover),

    x' = A x + B_ref s(t),     s = (r - p, r' - p', r'', w_ref, w_ref', p', p'')

with A the hover loop without a jet and B_ref its reference drive (``LoopMatrices.b_ref``). A vehicle
whose loops followed instantly (no inertia, no motor lag, no hold) would stay on the plan: the tilt
the force feed-forward asks for accelerates it by p'' exactly. What is left is the response this
module computes, e(t) = C x(t), from rest, exact for inputs linear between the samples
(first-order hold, :func:`proxplan.physics.discretize.foh_maps`).

**The set-point hold.** The firmware evaluates the reference every 1/100 s and holds it in between
(:data:`proxplan.physics.FIRMWARE_SETPOINT_RATE_HZ`): on average the reference is half a period old,
:data:`SETPOINT_DELAY_S`. The loop is driven by r, r', r'' and w_ref at t - that delay (the held
steps' ripple around that mean, at 100 Hz, is filtered by the airframe: m/s^2 for a few ms).

**After the plan.** The drive goes on over the reference's settle tail; what may remain of the
deviation after it is bounded by the loop's modes (A = V diag(lambda) V^-1, all damped):
|C x(t)| <= |C x_ss| + sum_i |C v_i| |(V^-1 (x_end - x_ss))_i|.

What it leaves out: the hover linearisation at large tilts (the thrust's magnitude m |p'' + g|
changing with the horizontal acceleration, second order), the hold's ripple, the integrators'
clamps, the motors' saturation; the measured tube the verifier grants besides covers them
(``Vehicle.tracking_tube_m``). World frame, z up; m, m/s, m/s^2, s, rad.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import signal

from proxplan.physics.controller_gains import FIRMWARE_SETPOINT_RATE_HZ
from proxplan.physics.discretize import foh_maps, zoh_maps
from proxplan.physics.hover_loop import _live_states, loop_matrices
from proxplan.physics.vehicles import GRAVITY_MPS2, Vehicle

SETPOINT_DELAY_S = 0.5 / FIRMWARE_SETPOINT_RATE_HZ
"""Mean age of a held set-point, s: half the firmware's set-point period (module docstring)."""


@dataclass(frozen=True)
class ReferenceSamples:
    """A vehicle's plan and the reference it flies, on a uniform grid ``t_s`` (K,), s: the plan's
    position, velocity, acceleration (K, 3 each; m, m/s, m/s^2) at t, and the reference's position,
    velocity, acceleration, jerk and snap (m ... m/s^4) at t - :data:`SETPOINT_DELAY_S`; world frame."""

    t_s: np.ndarray
    plan_position_m: np.ndarray
    plan_velocity_mps: np.ndarray
    plan_acceleration_mps2: np.ndarray
    ref_position_m: np.ndarray
    ref_velocity_mps: np.ndarray
    ref_acceleration_mps2: np.ndarray
    ref_jerk_mps3: np.ndarray
    ref_snap_mps4: np.ndarray


@dataclass(frozen=True)
class TrackingResponse:
    """The predicted deviation from the plan ``error_m`` (K, 3), m, on ``t_s`` (K,), s (the first
    ``n_plan`` samples of the drive's grid), and ``hold_error_m`` (m): the largest |deviation| after
    them (over the reference's tail, then bounded by the loop's modes)."""

    t_s: np.ndarray
    error_m: np.ndarray
    hold_error_m: float


def reference_drive(vehicle: Vehicle, ref: ReferenceSamples) -> np.ndarray:
    """The drive s (K, 21) of :data:`proxplan.physics.hover_loop.REFERENCE_INPUTS` for ``ref``
    (w_ref = (-jerk_y, jerk_x, 0) / g and its derivative from the snap, rad/s and rad/s^2)."""
    j, sn = ref.ref_jerk_mps3, ref.ref_snap_mps4
    zero = np.zeros(j.shape[0])
    w_ref = np.column_stack([-j[:, 1], j[:, 0], zero]) / GRAVITY_MPS2
    dw_ref = np.column_stack([-sn[:, 1], sn[:, 0], zero]) / GRAVITY_MPS2
    return np.concatenate(
        [
            ref.ref_position_m - ref.plan_position_m,
            ref.ref_velocity_mps - ref.plan_velocity_mps,
            ref.ref_acceleration_mps2,
            w_ref,
            dw_ref,
            ref.plan_velocity_mps,
            ref.plan_acceleration_mps2,
            frame_yaw_rate_radps(ref.ref_acceleration_mps2, ref.ref_jerk_mps3)[:, None],
        ],
        axis=1,
    )


def frame_yaw_rate_radps(acc_mps2: np.ndarray, jerk_mps3: np.ndarray) -> np.ndarray:
    """The rate (K,), rad/s, about its own z axis of the frame the firmware's attitude set-point
    follows at yaw 0 (z_B = (a + g e_z)/|a + g e_z|, y_B = z_B x e_x normalised, x_B = y_B x z_B;
    acceleration and jerk (K, 3), m/s^2 and m/s^3, world frame): w_z = -y_B' . x_B =
    -(z_B' x e_x) . x_B / |z_B x e_x|, z_B' = (j - (z_B . j) z_B)/|a + g e_z|. The firmware feeds
    forward w_z = z_B,z dyaw/dt = 0 (Mellinger & Kumar 2011 eq. 7), so on a curved path, where the
    tilt turns about the vertical, the frame turns away from the vehicle's heading at this rate."""
    n = np.atleast_2d(acc_mps2) + np.array([0.0, 0.0, GRAVITY_MPS2])
    mag = np.linalg.norm(n, axis=1, keepdims=True)
    z = n / mag
    j = np.atleast_2d(jerk_mps3)
    dz = (j - np.sum(z * j, axis=1, keepdims=True) * z) / mag
    ex = np.array([1.0, 0.0, 0.0])
    u = np.cross(z, ex)
    norm_u = np.linalg.norm(u, axis=1)
    x = np.cross(u / norm_u[:, None], z)
    return -np.sum(np.cross(dz, ex) * x, axis=1) / norm_u


def tracking_response(vehicle: Vehicle, ref: ReferenceSamples, n_plan: int | None = None) -> TrackingResponse:
    """The deviation of ``vehicle`` from its plan flying ``ref`` (module docstring), from rest, on
    the first ``n_plan`` samples (default all); the rest of the grid (the reference's tail) and the
    modal bound after it give ``hold_error_m``."""
    t = np.asarray(ref.t_s, dtype=float)
    k = t.size
    n_plan = k if n_plan is None else int(n_plan)
    s = reference_drive(vehicle, ref)
    mats = loop_matrices(vehicle)
    live = _live_states(mats.a)
    a = mats.a[0][np.ix_(live, live)]
    b = mats.b_ref[0][live]
    c = mats.c[:, live]
    err = np.zeros((k, 3))
    x = np.zeros(live.size)
    if k >= 2:
        step = float(t[1] - t[0])
        phi, g0, g1 = foh_maps(a, b, step)
        forced = s[:-1] @ (g0 - g1).T + s[1:] @ g1.T  # (K-1, n): the input's part of each step
        states = np.zeros_like(forced)
        twist = s[:, 21]
        turning = np.flatnonzero(np.abs(twist) > 0.0)
        n_seq = min(k - 1, int(turning[-1]) + 1) if turning.size else 0  # steps with the twist's coupling
        if n_seq:
            att = np.searchsorted(live, [6, 7, 8])  # roll, pitch, yaw in the live states
            b_att = np.zeros((1, live.size, 2))
            b_att[0, att[0], 0] = b_att[0, att[1], 1] = 1.0
            gam_att = zoh_maps(a[None], b_att, step)[1][0]
            w_ff = s[:, 9:11]
            for i in range(n_seq):  # the heading off the frame turns the roll / pitch feed-forward
                x = phi @ x + forced[i] + gam_att @ (x[att[2]] * np.array([-w_ff[i, 1], w_ff[i, 0]]))
                states[i] = x
        if n_seq < k - 1:
            rest = forced[n_seq:].copy()
            rest[0] += phi @ x
            states[n_seq:] = _recurrence(phi, rest)
        err[1:] = states @ c.T
        x = states[-1]
    after = float(np.linalg.norm(err[n_plan:], axis=1).max(initial=0.0))
    hold = max(after, _modal_bound(a, b, c, x, s[-1]))
    return TrackingResponse(t[:n_plan], err[:n_plan], hold)


MAX_MODAL_CONDITION = 1e8
"""The recurrence runs in the modes of Phi when its eigenvectors' condition number is below this
(the modal sums then lose < 1e-8 relative), else step by step, -."""


def _recurrence(phi: np.ndarray, forced: np.ndarray) -> np.ndarray:
    """x[k+1] = phi x[k] + forced[k] from x[0] = 0: the states x[1..K] (K, n). In the modes of phi
    (phi = V diag(mu) V^-1: each mode a first-order recursion, ``scipy.signal.lfilter``) when V is
    well conditioned, else step by step."""
    mu, vec = np.linalg.eig(phi)
    if np.linalg.cond(vec) < MAX_MODAL_CONDITION:
        z = np.linalg.inv(vec) @ forced.T  # (n, K)
        modes = np.stack([signal.lfilter([1.0], [1.0, -m], row) for m, row in zip(mu, z)])
        return (vec @ modes).real.T
    out = np.zeros_like(forced)
    x = np.zeros(phi.shape[0])
    for i in range(forced.shape[0]):
        x = phi @ x + forced[i]
        out[i] = x
    return out


def _modal_bound(a: np.ndarray, b: np.ndarray, c: np.ndarray, x_end: np.ndarray, s_end: np.ndarray) -> float:
    """Largest |C x(t)|, m, the loop (damped) can still reach from ``x_end`` with the drive held at
    ``s_end`` (module docstring); inf for a loop that is not damped."""
    lam, vec = np.linalg.eig(a)
    if np.max(lam.real) >= 0.0:
        return float(np.inf)
    x_ss = -np.linalg.solve(a, b @ s_end)
    start = np.linalg.solve(vec, x_end - x_ss)
    return float(np.linalg.norm(c @ x_ss) + np.sum(np.linalg.norm(c @ vec, axis=0) * np.abs(start)))
