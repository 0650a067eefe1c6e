"""The closed loop of a vehicle near hover under its controller, in a jet: the linear state-space
model, its poles (is the loop damped?) and its response to the jet along a plan.

**The loop** (the controller the simulator flies: the Crazyflie firmware's Mellinger law with the
vehicle's gains, ``Vehicle.controller``, :mod:`proxplan.physics.controller_gains`), linearised about
a level hover at yaw 0 with collective thrust T0 (m g minus the jet's vertical force, which the
integrator holds), deviations from the plan, world frame z up, body = world axes at the trim:

* rigid body: d' = v; m v' = T0 (theta, -phi, 0) + e_z u_T - c m v + f; (phi, theta, psi)' = w;
  J w' = u_M + tau + D w. c: rotor drag per axis (``Vehicle.drag_rate_ps``); D: the rotor-drag
  moment of a body rate (rotor i at r_i meets the air at w x r_i: diag(-2 k_z l^2, -2 k_z l^2,
  -4 k_d l^2) omega_hover, RotorPy's rotor drag, :mod:`proxplan.physics.rotor_drag`); f, tau: the
  jet's force (N) and torque (N m).
* motors: the delivered thrust and moments u = (u_T, u_M) follow the commanded ones through the
  rotors' first-order lag tau_m (``Vehicle.motor_time_constant_s``): tau_m u' = u_cmd - u.
* controller: Delta F = -k_p d - k_d v + k_i I_p (I_p' = -d); u_T,cmd = Delta F_z; the desired tilt
  (phi, theta)_des = (-Delta F_y, Delta F_x) / T0; e_R = (phi, theta, psi) - des;
  u_M,cmd = -k_R e_R - k_w w + k_I I_m - k_dw (w'_x, w'_y, 0) (I_m' = -e_R; the firmware's
  difference of consecutive rate errors is the derivative of -w at hover).
* the jet: f = F(t) + G_F d, tau = T(t) + G_T d + [T(t)]x (phi, theta, psi). F, T: the one model's
  wrench on the vehicle at its planned position; G_F, G_T (3 x 3, N/m and N m/m): its gradients with
  respect to the vehicle's position (finite differences of the model, :func:`wrench_gradient`);
  the last term: the model's wrench is that on a level vehicle with its torque about world axes,
  which the simulator applies in the body frame (R^T T: its attitude gradient is [T]x); its force
  stays in the world frame (no attitude gradient).

**A moving reference** (``LoopMatrices.b_ref``, :mod:`proxplan.physics.tracking_loop`): with the
position and velocity taken as deviations from the plan p and the rest as they are, a vehicle
flying a reference r obeys x' = A x + B_ref s, s = (r - p, r' - p', r'', w_ref, w_ref', p', p'',
w_frame): the force feed-forward q = m r'' + k_p (r - p) + k_d (r' - p') adds q_z to the thrust
command and (q_y, -q_x, 0) / T0 to the desired tilt, the rate feed-forward enters through k_w and
k_dw, r - p feeds the position integrator, the plan's motion leaves -(c p' + p'') on the velocity,
and the set-point frame's rate about its z axis w_frame (none fed forward) turns the heading off it.

22 states: d (3) m, v (3) m/s, (phi, theta, psi) (3) rad, w (3) rad/s, u (4) N and N m, I_p (3)
m s, I_m (3) rad s (:data:`STATE_NAMES`). Left out: the controller's 500 Hz sampling and 100 Hz
set-point hold (delays of ~1-5 ms, a phase of < 2 degrees at the loop's ~1 Hz), the integrators'
clamps, the motors' saturation, gyroscopic terms (second order at hover), the plan's own
acceleration in the trim (T0 uses m g).

**Damped or not** (:func:`loop_poles`): the rightmost eigenvalue of A(G_F, G_T) at a configuration.
Real part < 0: a deviation dies out (rate -Re, 1/s); >= 0: it grows: the vehicle oscillates in the
jet however good its plan (the margin is -Re).

**Response along a plan** (:func:`jet_response`): the deviation d solves the linear time-varying
system x' = A(t) x + B (F(t), T(t)) from rest (A(t) from the gradients at each sample), exact for
inputs and matrices held over each step (zero-order hold). The plan's undisturbed tracking error e
(|e| <= tube t, measured without a jet) also drives it, through G e: its part of d is bounded by
t gamma(t), gamma(t) = int_0^t ||C Phi(t, s) B G(s)||_F ds (the spectral norm bounded by the
Frobenius norm). After the last sample the configuration is held (the plan ends at rest): the hold is
stepped on a grid (C e^{A k h}, products of the final loop's matrices) and what can follow the grid is
bounded from the final loop's modes (every Re lambda < 0; one spectral projector P_m per cluster of
equal eigenvalues, :mod:`proxplan.physics.modal_bound`): |C x(t)| <= |C x_ss| + sum_m |C P_m (x(t_end)
- x_ss)| e^{Re lambda_m (t - t_end)}, the tube's blocks likewise.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from proxplan.physics.discretize import expm_stack, zoh_maps
from proxplan.physics.modal_bound import modal_bound
from proxplan.physics.tube_blocks import stepped_response
from proxplan.physics.vehicles import GRAVITY_MPS2, Vehicle

STATE_NAMES = (
    "d_x_m", "d_y_m", "d_z_m", "v_x_mps", "v_y_mps", "v_z_mps", "roll_rad", "pitch_rad", "yaw_rad",
    "w_x_radps", "w_y_radps", "w_z_radps", "u_T_N", "u_Mx_Nm", "u_My_Nm", "u_Mz_Nm",
    "int_ex_ms", "int_ey_ms", "int_ez_ms", "int_eRx_rads", "int_eRy_rads", "int_eRz_rads",
)  # fmt: skip
"""The states of the loop, in order (module docstring), with their units."""
N_STATES = len(STATE_NAMES)
_P, _V, _E, _W, _U, _IP, _IM = (
    slice(0, 3),
    slice(3, 6),
    slice(6, 9),
    slice(9, 12),
    slice(12, 16),
    slice(16, 19),
    slice(19, 22),
)

GRADIENT_STEP_M = 0.005
"""Step of the central differences of :func:`wrench_gradient`, m: the scale of the deviations the
loop sees (a tracking tube of 1-2 cm), small against the jet's width (a rotor disk, >= 2.5 cm)."""
MIN_THRUST_SHARE = 0.1
"""The trim thrust is kept >= this share of the weight (a jet pushing up harder than the weight
leaves no hover to linearise about), -."""


REFERENCE_INPUTS = (
    "lead_x_m", "lead_y_m", "lead_z_m", "lead_vx_mps", "lead_vy_mps", "lead_vz_mps",
    "ref_ax_mps2", "ref_ay_mps2", "ref_az_mps2", "ref_wx_radps", "ref_wy_radps", "ref_wz_radps",
    "ref_dwx_radps2", "ref_dwy_radps2", "ref_dwz_radps2", "plan_vx_mps", "plan_vy_mps", "plan_vz_mps",
    "plan_ax_mps2", "plan_ay_mps2", "plan_az_mps2", "frame_wz_radps",
)  # fmt: skip
"""The inputs of the reference drive ``b_ref`` (:func:`loop_matrices`), in order: the set-point
minus the plan (position m, velocity m/s), the set-point's acceleration (m/s^2), its body-rate
feed-forward and that rate's derivative (rad/s, rad/s^2), the plan's velocity and acceleration,
and the rate about its z axis (rad/s) of the frame the attitude set-point follows (the heading
leaves it at that rate: the firmware feeds none forward)."""
N_REFERENCE_INPUTS = len(REFERENCE_INPUTS)


@dataclass(frozen=True)
class LoopMatrices:
    """x' = a x + b (f, tau) + b_ref s per sample: ``a`` (K, 22, 22), ``b`` (K, 22, 6) (force N
    world, torque N m world axes), ``b_ref`` (K, 22, 22) the reference drive s
    (:data:`REFERENCE_INPUTS`: the deviation from the plan of a vehicle flying a moving reference,
    module docstring; None where not asked for); ``c`` (3, 22) picks the position deviation d, m."""

    a: np.ndarray
    b: np.ndarray
    c: np.ndarray
    b_ref: np.ndarray | None


def loop_matrices(
    vehicle: Vehicle,
    force_N: np.ndarray | None = None,
    torque_Nm: np.ndarray | None = None,
    force_gradient_Npm: np.ndarray | None = None,
    torque_gradient_Nmpm: np.ndarray | None = None,
    *,
    reference: bool = True,
) -> LoopMatrices:
    """The loop (module docstring) of ``vehicle`` in a jet with force (K, 3), N, torque (K, 3),
    N m (world frame) and their gradients (K, 3, 3) with respect to the vehicle's position, N/m and
    N m/m; None: no jet (one sample). ``reference=False``: no reference drive (``b_ref`` is
    None; the jet's response along a plan does not use it)."""
    arrays = [force_N, torque_Nm, force_gradient_Npm, torque_gradient_Nmpm]
    k = next((np.asarray(x).shape[0] for x in arrays if x is not None), 1)
    f0 = np.zeros((k, 3)) if force_N is None else np.asarray(force_N, dtype=float).reshape(k, 3)
    t0 = np.zeros((k, 3)) if torque_Nm is None else np.asarray(torque_Nm, dtype=float).reshape(k, 3)
    gf = np.zeros((k, 3, 3)) if force_gradient_Npm is None else np.asarray(force_gradient_Npm, dtype=float)
    gt = np.zeros((k, 3, 3)) if torque_gradient_Nmpm is None else np.asarray(torque_gradient_Nmpm, dtype=float)
    g = vehicle.controller
    m = vehicle.mass_kg
    jxx, jyy, jzz = vehicle.inertia_diag_kgm2
    j_inv = np.array([1.0 / jxx, 1.0 / jyy, 1.0 / jzz])
    thrust = np.maximum(m * GRAVITY_MPS2 - f0[:, 2], MIN_THRUST_SHARE * m * GRAVITY_MPS2)  # T0 (K,), N
    omega = vehicle.hover_omega_radps * np.sqrt(thrust / (m * GRAVITY_MPS2))  # rotor speed at the trim (K,)
    rd = vehicle.rotor_drag
    arm2 = vehicle.arm_length_m**2
    c_drag = vehicle.drag_rate_ps  # (3,) 1/s at the hover speed
    kp, kd, ki = g.kp_Npm, g.kd_Nspm, g.ki_Npms
    k_r = np.array([g.kR_xy_Nmprad, g.kR_xy_Nmprad, g.kR_z_Nmprad])
    k_w = np.array([g.kw_xy_Nmsprad, g.kw_xy_Nmsprad, g.kw_z_Nmsprad])
    k_i = np.array([g.ki_m_xy_Nmprads, g.ki_m_xy_Nmprads, g.ki_m_z_Nmprads])
    k_dw = np.array([g.kd_omega_rp_Nms2prad, g.kd_omega_rp_Nms2prad, 0.0])
    tau_m = vehicle.motor_time_constant_s

    a = np.zeros((k, N_STATES, N_STATES))
    b = np.zeros((k, N_STATES, 6))
    eye3 = np.eye(3)
    # jet: f = G_F d (+ input), tau = G_T d + [T]x att (+ input)
    cross_t = np.zeros((k, 3, 3))  # [T]x
    cross_t[:, 0, 1], cross_t[:, 0, 2], cross_t[:, 1, 2] = -t0[:, 2], t0[:, 1], -t0[:, 0]
    cross_t[:, 1, 0], cross_t[:, 2, 0], cross_t[:, 2, 1] = t0[:, 2], -t0[:, 1], t0[:, 0]
    # d' = v
    a[:, _P, _V] = eye3
    # m v' = T0 (theta, -phi, 0) + e_z u_T - c m v + f
    a[:, 3, 7] = thrust / m
    a[:, 4, 6] = -thrust / m
    a[:, 5, 12] = 1.0 / m
    a[:, _V, _V] -= np.sqrt(thrust / (m * GRAVITY_MPS2))[:, None, None] * np.diag(c_drag)[None]
    a[:, _V, _P] += gf / m
    b[:, _V, 0:3] = eye3 / m
    # att' = w
    a[:, _E, _W] = eye3
    # J w' = u_M + tau + D w  -> rows of w' (3, 22) per sample
    damp = -omega[:, None] * np.array([2.0 * rd.k_z_Ns2pradm * arm2, 2.0 * rd.k_z_Ns2pradm * arm2,
                                       4.0 * rd.k_d_Ns2pradm * arm2])  # fmt: skip
    wdot = np.zeros((k, 3, N_STATES))
    wdot[:, :, 13:16] = np.diag(j_inv)[None]
    wdot[:, :, 9:12] = np.einsum("i,ki,ij->kij", j_inv, damp, eye3)
    wdot[:, :, 0:3] = j_inv[None, :, None] * gt
    wdot[:, :, 6:9] = j_inv[None, :, None] * cross_t
    wdot_b = np.zeros((k, 3, 6))
    wdot_b[:, :, 3:6] = np.diag(j_inv)[None]
    a[:, _W, :] = wdot
    b[:, _W, :] = wdot_b
    # controller: Delta F rows (3, 22)
    dforce = np.zeros((3, N_STATES))
    dforce[:, _P] = -np.diag(kp)
    dforce[:, _V] = -np.diag(kd)
    dforce[:, _IP] = np.diag(ki)
    # e_R = att - (-dF_y, dF_x, 0) / T0
    e_r = np.zeros((k, 3, N_STATES))
    e_r[:, :, _E] = eye3
    e_r[:, 0, :] += dforce[1][None] / thrust[:, None]
    e_r[:, 1, :] -= dforce[0][None] / thrust[:, None]
    cmd = np.zeros((k, 4, N_STATES))
    cmd_b = np.zeros((k, 4, 6))
    cmd[:, 0, :] = dforce[2]
    cmd[:, 1:4, :] = -k_r[None, :, None] * e_r - k_dw[None, :, None] * wdot
    cmd[:, 1:4, _W] -= np.diag(k_w)[None]
    cmd[:, 1:4, _IM] += np.diag(k_i)[None]
    cmd_b[:, 1:4, :] = -k_dw[None, :, None] * wdot_b
    a[:, _U, :] = cmd / tau_m
    a[:, _U, _U] -= np.eye(4) / tau_m
    b[:, _U, :] = cmd_b / tau_m
    a[:, _IP, _P] = -eye3
    a[:, _IM, :] = -e_r
    c = np.zeros((3, N_STATES))
    c[:, _P] = eye3
    b_ref = _reference_drive(a, thrust, m, kp, kd, k_r, k_w, k_dw, tau_m) if reference else None
    return LoopMatrices(a, b, c, b_ref)


def _reference_drive(a, thrust, m, kp, kd, k_r, k_w, k_dw, tau_m) -> np.ndarray:
    """b_ref (K, 22, 22) of :class:`LoopMatrices` (module docstring, "a moving reference"): the
    force feed-forward q = m a_ref + k_p (r - p) + k_d (r' - v_plan) adds to the collective thrust
    command and tilts the desired attitude by (q_y, -q_x, 0) / T0 (e_R and its integrator); the rate
    feed-forward w_ref and its derivative enter the moment command through k_w and k_dw; r - p also
    feeds the position integrator; the plan's own motion leaves (c v_plan + a_plan) on the velocity."""
    k = a.shape[0]
    out = np.zeros((k, N_STATES, N_REFERENCE_INPUTS))
    eye3 = np.eye(3)
    q = np.zeros((3, N_REFERENCE_INPUTS))  # q per unit input
    q[:, 0:3] = np.diag(kp)
    q[:, 3:6] = np.diag(kd)
    q[:, 6:9] = m * eye3
    eps = np.zeros((k, 3, N_REFERENCE_INPUTS))  # the extra e_R
    eps[:, 0, :] = q[1][None] / thrust[:, None]
    eps[:, 1, :] = -q[0][None] / thrust[:, None]
    out[:, _V, 15:18] = a[:, _V, _V]  # the plan's velocity against the drag
    out[:, _V, 18:21] = -eye3
    out[:, _IP, 0:3] = eye3
    out[:, _IM, :] = -eps
    out[:, 12, :] = q[2][None] / tau_m
    moment = -k_r[None, :, None] * eps
    moment[:, :, 9:12] += np.diag(k_w)[None]
    moment[:, :, 12:15] += np.diag(k_dw)[None]
    out[:, 13:16, :] = moment / tau_m
    out[:, 8, 21] = -1.0  # the heading relative to the set-point's frame
    return out


@dataclass(frozen=True)
class LoopPoles:
    """Per sample (K,): the rightmost pole's real part ``growth_ps`` (1/s; < 0: damped, a deviation
    dies out at that rate; >= 0: it grows), its frequency ``frequency_hz`` (Hz) and damping ratio
    ``damping_ratio`` (-Re / |lambda|)."""

    growth_ps: np.ndarray
    frequency_hz: np.ndarray
    damping_ratio: np.ndarray


def _live_states(a: np.ndarray) -> np.ndarray:
    """Indices of the states something depends on: a state no other state reads (a zero column of
    every sample's A, e.g. an attitude integrator with k_I = 0) is a bare integrator of its own
    pole 0 that never acts on the vehicle, and is left out of the poles."""
    live = np.ones(a.shape[-1], dtype=bool)
    while True:
        sub = a[:, live][:, :, live]
        off = np.abs(sub).max(axis=0) * (1.0 - np.eye(sub.shape[-1]))
        dead = ~(off > 0.0).any(axis=0)
        if not dead.any():
            return np.flatnonzero(live)
        live[np.flatnonzero(live)[dead]] = False


def loop_poles(matrices: LoopMatrices) -> LoopPoles:
    """The rightmost pole of each sample's loop (:class:`LoopPoles`)."""
    live = _live_states(matrices.a)
    lam = np.linalg.eigvals(matrices.a[:, live][:, :, live])  # (K, n)
    pick = np.argmax(lam.real + 1e-9 * np.abs(lam.imag), axis=1)  # of equal real parts the oscillating one
    top = lam[np.arange(lam.shape[0]), pick]
    mag = np.maximum(np.abs(top), 1e-12)
    return LoopPoles(top.real, np.abs(top.imag) / (2.0 * np.pi), -top.real / mag)


def wrench_gradient(
    wrench: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
    positions_m: np.ndarray,
    step_m: float = GRADIENT_STEP_M,
) -> tuple[np.ndarray, np.ndarray]:
    """Gradients (K, 3, 3) of force (N/m) and torque (N m/m) with respect to the target's position,
    by central differences of ``wrench`` (positions (N, 3), m -> force (N, 3) N, torque (N, 3) N m:
    one of the model's wrench functions) at ``positions_m`` (K, 3), m; column j: d/d p_j."""
    pos = np.asarray(positions_m, dtype=float)
    k = pos.shape[0]
    shifted = np.concatenate([pos + s * step_m * e for e in np.eye(3) for s in (1.0, -1.0)])  # (6K, 3)
    force, torque = wrench(shifted)
    force, torque = force.reshape(3, 2, k, 3), torque.reshape(3, 2, k, 3)
    gf = np.transpose((force[:, 0] - force[:, 1]) / (2.0 * step_m), (1, 2, 0))
    gt = np.transpose((torque[:, 0] - torque[:, 1]) / (2.0 * step_m), (1, 2, 0))
    return gf, gt


HOLD_STEP_S = 0.02
"""Step on which the hold after a plan's end is evaluated in :func:`jet_response`, s (the loop's
fastest poles that matter, the ~1 Hz lateral mode, change by < 2 % of a period over it)."""
HOLD_MAX_S = 20.0
"""Longest hold evaluated in :func:`jet_response` before what is left is bounded by the loop's modes,
s (the lightly damped lateral modes of a vehicle in a jet that the verifier accepts, >= 0.1 1/s, have
lost 90 % by then; the integrators' slow modes are weakly excited)."""
HOLD_RESIDUAL_M = 1e-4
"""The hold is evaluated until the modal bound of what is left of the deviation stays below this, m,"""
HOLD_GAIN_RESIDUAL = 1e-3
"""... and of what is left of the tube gain below this, - (times a tube of 1-2 cm: 10-20 um)."""


@dataclass(frozen=True)
class JetResponse:
    """The loop's response along a plan (:func:`jet_response`) on its grid ``t_s`` (K,), s:
    ``deflection_m`` (K, 3), m, the deviation the jet's wrench along the plan drives, world frame;
    ``tube_gain`` (K,), -, gamma: a deviation within the tube t (without the jet) grows by at most
    t gamma in it; ``hold_deflection_m`` (m) and ``hold_tube_gain`` (-) the same bounds over the hold
    after the last sample (the final configuration held for ever; inf where the final loop is not
    damped); ``poles`` (one sample) of the configuration held at the end."""

    t_s: np.ndarray
    deflection_m: np.ndarray
    tube_gain: np.ndarray
    hold_deflection_m: float
    hold_tube_gain: float
    poles: LoopPoles


def jet_response(
    t_s: np.ndarray,
    vehicle: Vehicle,
    force_N: np.ndarray,
    torque_Nm: np.ndarray,
    force_gradient_Npm: np.ndarray,
    torque_gradient_Nmpm: np.ndarray,
    moving: np.ndarray | None = None,
    tracking_m: np.ndarray | None = None,
) -> JetResponse:
    """The loop of ``vehicle`` driven along a plan by the jet's force (K, 3), N, and torque (K, 3),
    N m (world frame), with their gradients (K, 3, 3) (N/m, N m/m), sampled on the uniform grid
    ``t_s`` (K,), s, from rest (module docstring). The tube's deviation drives the loop where the
    vehicle moves (``moving`` (K,) bool; None: everywhere; a vehicle at rest has no tracking error,
    as the verifier's tube), not over the hold after the end. ``tracking_m`` (K, 3), m: the
    vehicle's predicted deviation from its plan without the jet
    (:func:`proxplan.physics.tracking_response`); the jet's gradients act on it as an input
    (G e, force and torque), so ``deflection_m`` is what the jet adds to it (by linearity; the
    jet's shift of the trim thrust acting on the tracking's own tilt is left out, second order)."""
    t = np.asarray(t_s, dtype=float)
    kk = t.size
    f = np.asarray(force_N, dtype=float).reshape(kk, 3)
    tq = np.asarray(torque_Nm, dtype=float).reshape(kk, 3)
    gf = np.asarray(force_gradient_Npm, dtype=float).reshape(kk, 3, 3)
    gt = np.asarray(torque_gradient_Nmpm, dtype=float).reshape(kk, 3, 3)
    if kk < 2:
        mats = loop_matrices(vehicle, f, tq, gf, gt, reference=False)
        poles = loop_poles(LoopMatrices(mats.a[-1:], mats.b[-1:], mats.c, None))  # of the configuration held
        zero = JetResponse(t, np.zeros((kk, 3)), np.zeros(kk), 0.0, 0.0, poles)
        return _with_hold(zero, mats, np.zeros(N_STATES), np.zeros((N_STATES, 0)), f, tq)
    h = float(t[1] - t[0])
    u = np.concatenate([f, tq], axis=1)  # (K, 6)
    g_full = np.concatenate([gf, gt], axis=1)  # (K, 6, 3): the input per unit deviation
    g_in = g_full if moving is None else g_full * np.asarray(moving, dtype=bool)[:, None, None]
    # per step k -> k+1 the matrices of sample k (zero-order hold); consecutive steps with the
    # same sample values (force, torque and gradients: all the loop's matrices depend on) share
    # their matrices and maps (each map is the same whichever others it is computed with:
    # expm_stack's scaling is the largest norm of the distinct matrices)
    key = np.concatenate([u, g_full.reshape(kk, -1)], axis=1)[:-1]
    if tracking_m is not None:
        u = u + np.einsum("kij,kj->ki", g_full, np.asarray(tracking_m, dtype=float).reshape(kk, 3))
    change = np.concatenate([[True], (key[1:] != key[:-1]).any(axis=1)])
    inverse = np.cumsum(change) - 1
    rows = np.append(np.flatnonzero(change), kk - 1)  # the distinct steps' samples, then the last
    mats = loop_matrices(vehicle, f[rows], tq[rows], gf[rows], gt[rows], reference=False)
    poles = loop_poles(LoopMatrices(mats.a[-1:], mats.b[-1:], mats.c, None))  # of the configuration held at the end
    phi_u, gam_u = zoh_maps(mats.a[:-1], mats.b[:-1], h)
    gam = gam_u[inverse]
    drive = np.einsum("kij,kj->ki", gam, u[:-1])
    deflection, gain, x, blocks = stepped_response(phi_u, inverse, drive, gam @ g_in[:-1], mats.c)
    return _with_hold(JetResponse(t, deflection, gain, 0.0, 0.0, poles), mats, x, blocks, f, tq)


def _with_hold(resp, mats, x_end, blocks: np.ndarray, f, tq) -> JetResponse:
    """``resp`` with the bounds over the hold after its last sample (module docstring): the final
    configuration held (loop A, input u, constant), so from the end C x(t) = C x_ss +
    C e^{At} (x_end - x_ss), and each tube block likewise without the steady part; evaluated every
    :data:`HOLD_STEP_S` (C e^{A k h} = C Phi^k, Phi = e^{A h}, by doubling: products of the loop's
    own matrices, no eigenvector basis) until what the modes can still add (the modal bound of
    :mod:`proxplan.physics.modal_bound`, one spectral projector per cluster of equal eigenvalues:
    sound, and the same whichever basis of an x-y pair's eigenplane eig returns) stays below
    :data:`HOLD_RESIDUAL_M` and :data:`HOLD_GAIN_RESIDUAL` (or for :data:`HOLD_MAX_S`), which is
    then added: the samples plus the bound of all that can follow them."""
    live = _live_states(mats.a[-1:])
    a, b, c = mats.a[-1][np.ix_(live, live)], mats.b[-1][live], mats.c[:, live]
    bound = modal_bound(a, c) if resp.poles.growth_ps[0] < 0.0 else None
    if bound is None:
        return JetResponse(resp.t_s, resp.deflection_m, resp.tube_gain, np.inf, np.inf, resp.poles)
    u = np.concatenate([f[-1], tq[-1]])
    x_ss = -np.linalg.solve(a, b @ u)
    start = np.column_stack([x_end[live] - x_ss, blocks[live]])  # (n, 1 + 3 N)
    weight = bound.weights(start)  # (terms, 1 + 3N): what each term can add, at t = 0

    def residual(t: float) -> np.ndarray:  # per column (forced, then the blocks' columns), m
        return (weight * np.exp(-bound.rate_ps * t)[:, None]).sum(axis=0)

    def done(t: float) -> bool:
        rest = residual(t)
        return rest[0] < HOLD_RESIDUAL_M and float(rest[1:].sum()) < HOLD_GAIN_RESIDUAL

    horizon = 0.0
    while horizon < HOLD_MAX_S and not done(horizon):
        horizon = min(2.0 * horizon + HOLD_STEP_S, HOLD_MAX_S)
    times = np.arange(0.0, horizon + HOLD_STEP_S / 2, HOLD_STEP_S)
    rows, power = c[None], expm_stack(a[None] * HOLD_STEP_S)[0]  # C Phi^k for k < 1, Phi^1
    while rows.shape[0] < times.size:
        rows = np.concatenate([rows, rows @ power])  # C Phi^k for k < 2 k_before
        power = power @ power
    y_ss = c @ x_ss
    worst_d, worst_g = 0.0, 0.0
    for chunk in np.array_split(np.arange(times.size), max(1, times.size // 500)):
        traj = rows[chunk] @ start  # (T, 3, 1 + 3N)
        worst_d = max(worst_d, float(np.linalg.norm(y_ss[None] + traj[:, :, 0], axis=1).max()))
        if start.shape[1] > 1:
            blocks = traj[:, :, 1:].reshape(chunk.size, 3, -1, 3)
            worst_g = max(worst_g, float(np.sqrt((blocks**2).sum(axis=(1, 3))).sum(axis=1).max()))
    rest = residual(times[-1])
    worst_d += float(rest[0])
    worst_g += float(rest[1:].sum())
    return JetResponse(resp.t_s, resp.deflection_m, resp.tube_gain, worst_d, worst_g, resp.poles)


def weak_jet_bound_m(vehicle: Vehicle, force_max_N: float, torque_max_Nm: float) -> float:
    """Largest deviation, m, that any force of norm <= ``force_max_N`` (N) and torque of norm <=
    ``torque_max_Nm`` (N m) can drive in the vehicle's loop without a jet (the jet's gradients left
    out: for a jet too weak to matter): the L1 norm of the loop's impulse response bounded by its
    modal bound (:mod:`proxplan.physics.modal_bound`: |C e^{At} B u| <= sum_m ||M_m B|| |u| e^{-r_m t}),
    sum_m (||M_m B_F|| F + ||M_m B_T|| T) / r_m (spectral norms; for a simple eigenvalue
    ||C P_i B_F|| = |C v_i| |w_i B_F|); inf for a loop that is not damped."""
    mats = loop_matrices(vehicle)
    live = _live_states(mats.a)
    a, b, c = mats.a[0][np.ix_(live, live)], mats.b[0][live], mats.c[:, live]
    bound = modal_bound(a, c)
    if bound is None:
        return float(np.inf)
    per = bound.operator_norms(b[:, :3]) * force_max_N + bound.operator_norms(b[:, 3:]) * torque_max_Nm
    return float(np.sum(per / bound.rate_ps))
