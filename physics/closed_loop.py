"""The closed loop of a vehicle under its position / attitude controller, reduced per axis near
hover: the lead a reference needs so that the vehicle flies its plan, and the path a given
reference is predicted to fly. (The deflection a disturbance causes, in a jet whose wrench changes
with the vehicle's position, is the full loop's: :mod:`proxplan.physics.hover_loop`.)

The model, per world axis, from the Mellinger law the vehicle flies (gains: ``Vehicle.controller``,
:mod:`proxplan.physics.controller_gains`) and the rotor drag it meets (``Vehicle.drag_rate_ps``, c,
1/s, :mod:`proxplan.physics.rotor_drag`); e = r - x is the position error against the reference r:

* force wanted: F = m r'' + k_p e + k_d e' + k_i int(e) dt; the vehicle: m x'' = F_delivered - c m x'.
* **Horizontal** (x, y): F is delivered by tilting. The attitude loop tracks the tilt F / (m g)
  with its rate feed-forward w_ref = r''' / g (the firmware's differential flatness) and the
  rate-error derivative: 0 = k_R (theta_des - theta) + k_w (w_ref - theta') + k_dw (w_ref' - theta'')
  (the airframe's inertia and motor lag taken as fast; roll / pitch gains in N m/rad). Eliminating
  theta = (x'' + c x') / g gives, for the lead delta = r - p that keeps x = p:

      (m k_dw/k_R) delta'''' + (m k_w/k_R) delta''' + m delta'' + k_d delta' + k_p delta + k_i int(delta)
          = c m v + (m k_w/k_R) c a + (m k_dw/k_R) c j

  (v, a, j: the plan's velocity, acceleration, jerk). Without the attitude terms this is
  m delta'' + k_d delta' + k_p delta + k_i int(delta) = c m v, whose steady state at constant speed
  (k_i = 0) is c m v / k_p: ~1.9 cm per m/s for a Crazyflie (kp_xy 0.4 N/m on 32 g, c 0.24 1/s).
  The attitude terms put the drag's share of the tilt into the reference's jerk, where the
  firmware's rate feed-forward sees it.
* **Vertical** (z): F is the collective thrust, delivered through the motors' first-order lag
  tau (``Vehicle.motor_time_constant_s``): tau F_d' + F_d = F. For x = p:

      m delta'' + k_d delta' + k_p delta + k_i int(delta) = c m v + tau m (j + c a),

  A jump of the plan's jerk would make the reference's acceleration jump by tau j, which no C2
  upload holds: the plan the lead is computed for is first averaged over tau
  (:func:`proxplan.planfile.reference.smoothed_plan`), which makes its jerk continuous.

* **Prediction** (:func:`reference_error`): the same model run forwards from a given reference r
  (an upload): the lag e = r - x solves
  xy: (m k_dw/k_R) e'''' + (m/k_R)(k_w + k_dw c) e''' + m (1 + k_w c/k_R) e'' + (k_d + c m) e' + k_p e
  + k_i int(e) = c m r' + (m k_w/k_R) c r'' + (m k_dw/k_R) c r''';
  z: tau m e''' + m (1 + tau c) e'' + (k_d + c m) e' + k_p e + k_i int(e) = c m r' + tau c m r'' + tau m r'''.
  For r = p + delta it gives e = delta exactly: the compensated reference is predicted to fly the plan.
After a plan ends (v = 0) the lead keeps solving its equation: the integrator wound up by the
flight unwinds over the *settle tail* (:data:`TAIL_RESIDUAL_M`, :data:`TAIL_MAX_S`).

Everything starts from rest (zero state and integrators: deviations from a steady hover) and is
solved exactly for inputs linear between samples (first-order hold, :mod:`proxplan.physics.discretize`). Frames: world, z up;
m, m/s, m/s^2, N, s. What the model leaves out: the airframe's attitude inertia and the motors'
lag on the torques (the firmware's rate feed-forward covers most of it), the 100 Hz set-point
hold, the drag's dependence on tilt and rotor speed away from hover, the integrators' clamps.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from proxplan.physics.discretize import foh_maps, recurrence
from proxplan.physics.vehicles import Vehicle

TAIL_RESIDUAL_M = 0.0005
"""The settle tail ends once the lead stays within this, m (and its rate within it per second)."""
TAIL_MAX_S = 30.0
"""Longest settle tail, s: the firmware's x-y integrator unwinds with k_i / k_p ~ 0.125 1/s."""


@dataclass(frozen=True)
class LoopResponse:
    """A response (K, 3), m, and its first two time derivatives, on ``t_s`` (K,), s (world frame)."""

    t_s: np.ndarray
    value: np.ndarray  # m
    rate: np.ndarray  # m/s
    accel: np.ndarray  # m/s^2


def _solve(t_s: np.ndarray, coefficients: list[list[float]], drive_N: np.ndarray) -> LoopResponse:
    """Solve, per axis k, ki int(y) + c0 y + c1 y' + ... + cn y^(n) = drive_k from rest, with
    ``coefficients[k]`` = [ki, c0, ..., cn] (cn != 0, n >= 2) and ``drive_N`` (K, 3) linear
    between the samples of the uniform grid ``t_s`` (K,), s: exact for such inputs (first-order
    hold discretisation, :func:`proxplan.physics.discretize.foh_maps`), the states stepped
    (:func:`proxplan.physics.discretize.recurrence`: no zeros and poles, whose root finding on
    poles clustered near z = 1 made the result depend on the CPU's BLAS kernel at 3e-4 of the
    jerk, stop 49)."""
    t = np.asarray(t_s, dtype=float)
    value, rate, accel = (np.zeros((t.size, 3)) for _ in range(3))
    if t.size < 2:
        return LoopResponse(t, value, rate, accel)
    step = float(t[1] - t[0])
    keys = [tuple(float(c) for c in coef) for coef in coefficients]
    for key in dict.fromkeys(keys):  # axes with the same equation side by side
        axes = [k for k in range(len(keys)) if keys[k] == key]
        phi, g0, g1, out_c, out_d = _maps(key, step)
        u = np.asarray(drive_N[:, axes], dtype=float).T  # (axes, K)
        states = np.zeros((g0.size, len(axes), t.size))
        states[..., 1:] = recurrence(phi, (g0 - g1)[:, None, None] * u[:, :-1] + g1[:, None, None] * u[:, 1:])
        y = np.einsum("ij,jak->iak", out_c, states) + out_d[:, None, None] * u  # (3, axes, K): y, y', y''
        value[:, axes], rate[:, axes], accel[:, axes] = (r.T for r in y)
    return LoopResponse(t, value, rate, accel)


@functools.lru_cache(maxsize=256)
def _maps(coef: tuple[float, ...], step_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The first-order-hold maps (Phi (n, n), Gamma_0, Gamma_1 (n,)) of :func:`_solve`'s equation
    over ``step_s`` (s), in the states int(y), y, y', ..., y^(n-1), and the outputs y, y', y'' =
    out_c (3, n) x + out_d (3,) drive."""
    c = list(coef)
    while c[-1] == 0.0:
        c.pop()
    n = len(c) - 1  # states: int(y), y, y', ..., y^(n-1)
    a = np.zeros((n, n))
    a[np.arange(n - 1), np.arange(1, n)] = 1.0
    a[-1] = -np.array(c[:-1]) / c[-1]
    b = np.zeros((n, 1))
    b[-1, 0] = 1.0 / c[-1]
    out_c = np.zeros((3, n))
    out_d = np.zeros(3)
    out_c[0, 1] = out_c[1, 2] = 1.0  # y, y'
    if n > 3:
        out_c[2, 3] = 1.0  # y''
    else:  # y'' = (drive - sum c_i state_i) / c_n
        out_c[2] = -np.array(c[:-1]) / c[-1]
        out_d[2] = 1.0 / c[-1]
    phi, g0, g1 = foh_maps(a, b, step_s)
    return phi, g0[:, 0], g1[:, 0], out_c, out_d


@dataclass(frozen=True)
class _Loop:
    """The numbers of the model (module docstring) per world axis: mass m kg, gains kp N/m, kd N s/m,
    ki N/(m s), drag c m N s/m, the horizontal attitude ratios m k_w / k_R and m k_dw / k_R (s, s^2
    times kg... as N s^2/m and N s^3/m) and the motor lag tau, s."""

    m: float
    kp: np.ndarray
    kd: np.ndarray
    ki: np.ndarray
    cm: np.ndarray
    a3: float  # m k_w / k_R, kg s
    a4: float  # m k_dw / k_R, kg s^2
    tau: float


def _loop(vehicle: Vehicle) -> _Loop:
    g = vehicle.controller
    m = vehicle.mass_kg
    return _Loop(
        m,
        g.kp_Npm,
        g.kd_Nspm,
        g.ki_Npms,
        vehicle.drag_rate_ps * m,
        m * g.kw_xy_Nmsprad / g.kR_xy_Nmprad,
        m * g.kd_omega_rp_Nms2prad / g.kR_xy_Nmprad,
        vehicle.motor_time_constant_s,
    )


def drag_lead(
    t_s: np.ndarray,
    velocity_mps: np.ndarray,
    acceleration_mps2: np.ndarray,
    jerk_mps3: np.ndarray,
    vehicle: Vehicle,
    *,
    tail: bool = True,
    tail_residual_m: float = TAIL_RESIDUAL_M,
    tail_max_s: float = TAIL_MAX_S,
    end_multiple: int = 1,
) -> LoopResponse:
    """The lead delta = r - p (module docstring) of a plan with velocity, acceleration and jerk
    (K, 3 each; m/s, m/s^2, m/s^3) on the uniform grid ``t_s`` (K,), s, from rest. With ``tail``
    the grid goes on after the plan's end (at rest) until the lead and its rate stay within
    ``tail_residual_m`` (m, m/s) or for ``tail_max_s`` (s), whichever comes first; the number of
    tail samples is a multiple of ``end_multiple`` (so the tail ends on a coarser grid)."""
    t = np.asarray(t_s, dtype=float)
    v, a, j = (np.asarray(x, dtype=float) for x in (velocity_mps, acceleration_mps2, jerk_mps3))
    n_plan = t.size
    if tail and n_plan >= 2:
        step = float(t[1] - t[0])
        n_extra = -(-int(np.ceil(tail_max_s / step)) // end_multiple) * end_multiple
        t = np.concatenate([t, t[-1] + step * np.arange(1, n_extra + 1)])
        v, a, j = (np.vstack([x, np.zeros((n_extra, 3))]) for x in (v, a, j))
    lp = _loop(vehicle)
    c = lp.cm / lp.m  # 1/s
    drive = lp.cm * v
    drive[:, :2] += lp.a3 * c[:2] * a[:, :2] + lp.a4 * c[:2] * j[:, :2]
    drive[:, 2] += lp.tau * (lp.m * j[:, 2] + lp.cm[2] * a[:, 2])
    coefficients = [[lp.ki[k], lp.kp[k], lp.kd[k], lp.m, lp.a3, lp.a4] for k in range(2)]
    coefficients.append([lp.ki[2], lp.kp[2], lp.kd[2], lp.m])
    out = _solve(t, coefficients, drive)
    if not tail or n_plan < 2:
        return out
    over = (np.abs(out.value) > tail_residual_m) | (np.abs(out.rate) > tail_residual_m)
    late = np.flatnonzero(over.any(axis=1)[n_plan:])
    n_tail = int(late[-1]) + 2 if late.size else 0  # to the first sample within the residual after the last outside
    n_tail = min(-(-n_tail // end_multiple) * end_multiple, t.size - n_plan)
    end = n_plan + n_tail
    return LoopResponse(t[:end], out.value[:end], out.rate[:end], out.accel[:end])


def reference_error(
    t_s: np.ndarray,
    ref_velocity_mps: np.ndarray,
    ref_acceleration_mps2: np.ndarray,
    ref_jerk_mps3: np.ndarray,
    vehicle: Vehicle,
) -> LoopResponse:
    """How far the vehicle is predicted to lag a reference with velocity, acceleration and jerk
    (K, 3 each; m/s, m/s^2, m/s^3) on the uniform grid ``t_s`` (K,), s: e = r - x, from rest
    (module docstring)."""
    v, a, j = (np.asarray(x, dtype=float) for x in (ref_velocity_mps, ref_acceleration_mps2, ref_jerk_mps3))
    lp = _loop(vehicle)
    c = lp.cm / lp.m  # 1/s
    drive = lp.cm * v
    drive[:, :2] += lp.a3 * c[:2] * a[:, :2] + lp.a4 * c[:2] * j[:, :2]
    drive[:, 2] += lp.tau * (lp.cm[2] * a[:, 2] + lp.m * j[:, 2])
    coefficients = [
        [lp.ki[k], lp.kp[k], lp.kd[k] + lp.cm[k], lp.m + lp.a3 * c[k], lp.a3 + lp.a4 * c[k], lp.a4] for k in range(2)
    ]
    coefficients.append([lp.ki[2], lp.kp[2], lp.kd[2] + lp.cm[2], lp.m * (1.0 + lp.tau * c[2]), lp.tau * lp.m])
    return _solve(np.asarray(t_s, dtype=float), coefficients, drive)
