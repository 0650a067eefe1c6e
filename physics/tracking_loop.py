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

    x' = A x + B_ref s(t),     s = (r - p, r' - p', r'', w_ref, w_ref', p', p'', w_frame)

with A the hover loop without a jet and B_ref its reference drive (``LoopMatrices.b_ref``). A vehicle
whose loops followed instantly (no inertia, no motor lag, no hold) would stay on the plan: the tilt
the force feed-forward asks for accelerates it by p'' exactly. What is left is the response this
module computes, e(t) = C x(t), from rest, exact for inputs linear between the samples
(first-order hold, :func:`proxplan.physics.discretize.foh_maps`).

**The set-point hold.** The firmware evaluates the reference every 1/100 s and holds it in between
(:data:`proxplan.physics.FIRMWARE_SETPOINT_RATE_HZ`): on average the reference is half a period old,
:data:`SETPOINT_DELAY_S`. The loop is driven by r, r', r'' and w_ref at t - that delay (the held
steps' ripple around that mean, at 100 Hz, is filtered by the airframe: m/s^2 for a few ms).

**The heading on curves.** At yaw 0 the attitude set-point's frame is y_B = z_B x e_x normalised;
where the tilt turns about the vertical (a curve, a diagonal) that frame turns about its own z axis
at w_frame (:func:`frame_yaw_rate_radps`), which the firmware does not feed forward (it feeds
z_B,z dyaw/dt = 0, Mellinger & Kumar 2011 eq. 7): the heading psi falls behind (psi' gets
-w_frame), and a heading off the frame turns the roll / pitch feed-forward about the vertical:
(phi, theta)' gets psi (-w_ref,y, w_ref,x), the one time-varying term, stepped through (zero-order
hold of psi) where the frame turns.

**After the plan.** The drive goes on over the reference's settle tail (on a grid of
:data:`TAIL_STEP_S`); what may remain of the
deviation after it is bounded by the loop's modes (all damped; one spectral projector P_m per cluster
of equal eigenvalues, :mod:`proxplan.physics.modal_bound`):
|C x(t)| <= |C x_ss| + sum_m |C P_m (x_end - x_ss)| (+ terms of ~ 1e-16 for pairs split by rounding).

What it leaves out: the hover linearisation at large tilts (the thrust's magnitude m |p'' + g|
changing with the horizontal acceleration, second order), the hold's ripple and the steps of the
rate-error derivative at each new set-point (they saturate the motors for a few ms), the
integrators' clamps; the measured tube the verifier grants besides covers them
(``Vehicle.tracking_tube_m``). World frame, z up; m, m/s, m/s^2, s, rad.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from proxplan.physics.controller_gains import FIRMWARE_SETPOINT_RATE_HZ
from proxplan.physics.discretize import foh_maps, recurrence, zoh_maps
from proxplan.physics.hover_loop import _live_states, loop_matrices
from proxplan.physics.modal_bound import ModalBound, modal_bound
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
    """The predicted deviation from the plan ``error_m`` (K, 3), m, on ``t_s`` (K,), s, and
    ``hold_error_m`` (m): the largest |deviation| after them (over the reference's settle tail, then
    bounded by the loop's modes)."""

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


TAIL_STEP_S = 0.05
"""Step of the grid the reference's settle tail is sampled on, s: the tail's drive (the lead
unwinding at the integrators' rate, ~0.1 1/s) is smooth, so the first-order hold stays exact to
well under a micrometre on it."""


@dataclass(frozen=True)
class _Maps:
    """The loop without a jet on its live states, discretised over one step (first-order hold),
    the twist's input map (zero-order hold) and the bound on what the loop does left to itself
    (:mod:`proxplan.physics.modal_bound`; None when it is not damped)."""

    live: np.ndarray
    a: np.ndarray
    b: np.ndarray
    c: np.ndarray
    phi: np.ndarray
    g0: np.ndarray
    g1: np.ndarray
    g_att: np.ndarray
    bound: ModalBound | None


@functools.lru_cache(maxsize=64)
def _maps(vehicle: Vehicle, step_s: float) -> _Maps:
    mats = loop_matrices(vehicle)
    assert mats.b_ref is not None
    live = _live_states(mats.a)
    a = mats.a[0][np.ix_(live, live)]
    b = mats.b_ref[0][live]
    phi, g0, g1 = foh_maps(a, b, step_s)
    att = np.searchsorted(live, [6, 7])  # roll, pitch in the live states
    b_att = np.zeros((1, live.size, 2))
    b_att[0, att[0], 0] = b_att[0, att[1], 1] = 1.0
    g_att = zoh_maps(a[None], b_att, step_s)[1][0]
    return _Maps(live, a, b, mats.c[:, live], phi, g0, g1, g_att, modal_bound(a, mats.c[:, live]))


def tracking_response(
    vehicle: Vehicle, ref: ReferenceSamples, tail: ReferenceSamples | None = None
) -> TrackingResponse:
    """The deviation of ``vehicle`` from its plan flying ``ref`` (module docstring), from rest, on
    ``ref``'s grid; ``hold_error_m`` from the reference's settle ``tail`` (samples from ``ref``'s
    last time on, on a grid of its own) and the modal bound after it."""
    t = np.asarray(ref.t_s, dtype=float)
    s = reference_drive(vehicle, ref)
    step = float(t[1] - t[0]) if t.size >= 2 else TAIL_STEP_S
    m = _maps(vehicle, step)
    states = _run(m, s, np.zeros(m.live.size), twist=True)
    err = states @ m.c.T
    x, s_end, after = states[-1], s[-1], 0.0
    if tail is not None and tail.t_s.size >= 2:
        s_tail = reference_drive(vehicle, tail)
        m_tail = _maps(vehicle, float(tail.t_s[1] - tail.t_s[0]))
        tail_states = _run(m_tail, s_tail, x, twist=False)
        after = float(np.linalg.norm(tail_states @ m.c.T, axis=1).max())
        x, s_end = tail_states[-1], s_tail[-1]
    rest = np.zeros_like(s_end)  # held at rest after the tail: only the reference's offset from the plan
    rest[0:3] = s_end[0:3]
    hold = max(after, _modal_bound(m, x, rest))
    return TrackingResponse(t, err, hold)


def _run(m: _Maps, s: np.ndarray, x0: np.ndarray, *, twist: bool) -> np.ndarray:
    """The states (K, n) on the drive's grid (K samples of ``s``) from ``x0`` at its first sample;
    with ``twist`` the heading's turn of the roll / pitch feed-forward (module docstring) where the
    set-point frame turns. The heading's subsystem (:func:`_heading_states`) is closed in Phi and
    the twist does not enter it, so its states follow from its own recursion first; the twist is
    then a known drive, and the whole run one :func:`proxplan.physics.discretize.recurrence`
    (~2 sqrt(K) Python-level steps instead of one per sample up to the last turn)."""
    k = s.shape[0]
    states = np.zeros((k, x0.size))
    states[0] = x0
    if k < 2:
        return states
    forced = np.einsum("ki,ji->kj", s[:-1], m.g0 - m.g1) + np.einsum("ki,ji->kj", s[1:], m.g1)  # (K-1, n)
    turning = np.flatnonzero(np.abs(s[:, 21]) > 0.0) if twist else np.zeros(0, dtype=int)
    n_seq = min(k - 1, int(turning[-1]) + 1) if turning.size else 0
    yaw = int(np.searchsorted(m.live, 8))
    heading = _heading_states(m, yaw) if n_seq else None
    first = 0
    if heading is not None:
        sub = np.ix_(heading, heading)
        head = forced[:n_seq, heading].copy()
        head[0] += m.phi[sub] @ x0[heading]
        psi = np.concatenate([[x0[yaw]], recurrence(m.phi[sub], head.T)[int(np.searchsorted(heading, yaw))]])
        forced = forced.copy()  # x_att += G_att yaw (-w_ff,y, w_ff,x), the heading known
        forced[:n_seq] += (psi[:n_seq, None] * np.column_stack([-s[:n_seq, 10], s[:n_seq, 9]])) @ m.g_att.T
    elif n_seq:  # not closed: step where the frame turns
        x = x0
        for i in range(n_seq):  # x_att += G_att yaw (-w_ff,y, w_ff,x)
            x = m.phi @ x + forced[i] + m.g_att @ (x[yaw] * np.array([-s[i, 10], s[i, 9]]))
            states[i + 1] = x
        x0, forced, first = x, forced[n_seq:], n_seq
    if first < k - 1:
        rest = forced.copy()
        rest[0] += m.phi @ x0
        states[first + 1 :] = recurrence(m.phi, rest.T).T
    return states


def _heading_states(m: _Maps, yaw: int) -> np.ndarray | None:
    """The live states the heading (index ``yaw``) depends on through Phi (itself, its rate, the
    yaw moment and its integrator at hover without a jet), sorted, when the twist's input map
    ``g_att`` leaves all of them alone (exact zeros: their recursion is then that of the plain
    loop); None otherwise."""
    dep = np.zeros(m.live.size, dtype=bool)
    dep[yaw] = True
    while True:
        grown = dep | (m.phi[dep] != 0.0).any(axis=0)
        if (grown == dep).all():
            break
        dep = grown
    return None if (m.g_att[dep] != 0.0).any() else np.flatnonzero(dep)


def _modal_bound(m: _Maps, x_end: np.ndarray, s_end: np.ndarray) -> float:
    """Largest |C x(t)|, m, the loop (damped) can still reach from ``x_end`` with the drive held at
    ``s_end`` (module docstring: |C x_ss| + the modal bound at t = 0); inf for a loop that is not
    damped."""
    if m.bound is None:
        return float(np.inf)
    x_ss = -np.linalg.solve(m.a, m.b @ s_end)
    return float(np.linalg.norm(m.c @ x_ss) + m.bound.weights((x_end - x_ss)[:, None]).sum())
