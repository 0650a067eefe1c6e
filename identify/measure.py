"""Disturbance wrench measured from IMU and motor data (S0-9..S0-14).

Force (S0-11), world frame:   f_a = m R alpha - (sum_i f_i) R z_B
    with R alpha the accelerometer's specific force rotated to the world frame (+g on z in hover).
Torque (S0-13) plus the gyroscopic term S0-13 omits, world frame:
    tau_a = R (J omega_dot + omega x J omega) - R tau_p
    with tau_p the body torque of the motors from the (S0-14) mixer (arms l/sqrt2, k_t), taken from
    :func:`proxplan.physics.authority.mixer_matrix` so the mixer exists once.

Both sides of (S0-13) pass ONE filter: per sample the balance J omega_dot + omega x J omega - tau_p is formed,
omega_dot the central difference of the gyro (omega[k+1] - omega[k-1]) / 2h, the mean angular acceleration over
the two steps around the sample, and the balance is then smoothed as a whole by the measurement's smoother: a
Savitzky-Golay fit over ``window_s`` (default; ``scipy.signal.savgol_filter``) or the paper's triangular moving
average (S0-12); the force is smoothed by the same smoother. ``derivative="difference"`` keeps the raw forward
difference (S0-12) with no smoothing. (Until stop 81 the Savitzky-Golay DERIVATIVE of omega met the Savitzky-Golay
SMOOTHING of tau_p: two kernels (the window's slope averages omega_dot with a parabolic weight, the order-2 fit
passes more of a fast change), so wherever a vehicle rotates, its controller's motor torque and its angular
acceleration were averaged two ways and the difference was measured as a disturbance that lags the true one. On
the flown bench world's clean sets that was 25-45 % of the true torque's RMS (measured minus applied, both
smoothed alike), 3-4 % with one filter (docs/identify.md, stop 81).) Optional first-order motor-lag compensation
passes the commanded thrusts through f' = (f_cmd - f) / tau_motor before they enter (S0-11, S0-14).

Derivatives and smoothing run per contiguous segment (``segment`` ids from the log checks) and
assume a uniform sample time within a segment (the median step).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.ndimage import convolve1d
from scipy.signal import lfilter, lfilter_zi, savgol_coeffs, savgol_filter
from scipy.signal.windows import triang
from scipy.spatial.transform import Rotation

from proxplan.physics import Vehicle

DERIVATIVES = ("savgol", "triangular", "difference")
FREE_HEIGHT_M = 0.3
"""Free flight: rotor plane at least this high above the ground (out of ground effect), m (used by the
motor-lag self-check and the free-flight thrust scale)."""


@dataclass(frozen=True)
class MeasureOptions:
    """How the disturbance is measured."""

    derivative: str = "savgol"  # one of DERIVATIVES
    window_s: float = 0.15  # smoothing / derivative window, s
    polyorder: int = 2  # Savitzky-Golay polynomial order, -
    motor_time_constant_s: float | None = None  # first-order motor lag tau to compensate, s (None: see motor_lag)
    motor_lag: bool = True  # where logs hold COMMANDED thrust, compensate each vehicle's own
    # Vehicle.motor_time_constant_s (proxplan.identify.loading.measure_options_for); an explicit
    # motor_time_constant_s overrides the vehicle's value
    thrust_scale: float = 1.0  # multiplies the logged motor thrusts (calibrated), -
    command_interpolation: float = 0.0  # how the logged command runs between two samples, -: 0 held from each
    # sample to the next (zero-order hold), 1 linear from each sample to the next (first-order hold); the
    # motor lag's input (motor_lag_compensated_N)
    command_interpolation_by_type: tuple[tuple[str, float], ...] = ()  # (vehicle type, p) chosen by
    # proxplan.identify.command_check; load_units sets command_interpolation from it per vehicle (types not
    # named: command_interpolation as given)

    def __post_init__(self) -> None:
        if self.derivative not in DERIVATIVES:
            raise ValueError(f"derivative must be one of {DERIVATIVES}, got {self.derivative!r}")


@dataclass(frozen=True)
class MeasuredWrench:
    """Measured aerodynamic disturbance on one vehicle over N samples, world frame."""

    force_N: np.ndarray  # (N, 3), N
    torque_Nm: np.ndarray  # (N, 3), N m


def _window_samples(window_s: float, dt_s: float, n: int, polyorder: int) -> int:
    w = max(int(round(window_s / dt_s)) | 1, polyorder + 2 | 1)
    return min(w, n if n % 2 else n - 1)


@lru_cache(maxsize=256)
def _savgol_operator(w: int, polyorder: int, deriv: int, delta_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The Savitzky-Golay filter of ``savgol_filter(x, w, polyorder, deriv, delta_s, mode="interp")`` as linear
    maps, built once per window: its convolution coefficients (w,) and its two edges, (w // 2, w) each: the
    polynomial fitted to the first (last) w samples evaluated at the first (last) w // 2. The edges are
    scipy's own edge fit applied to the identity (each column the filter's response to one unit sample), so
    they are the same least-squares fit, rounded once here instead of at every call (scipy fits each
    edge again per call: two ``lstsq`` of a w-row Vandermonde matrix, 2/3 of the filter's time on the
    identify pipeline's many short stretches). Units: the output's per ``delta_s`` (s) ** ``deriv``."""
    coeffs = savgol_coeffs(w, polyorder, deriv=deriv, delta=delta_s)
    response = savgol_filter(np.eye(w), w, polyorder, deriv=deriv, delta=delta_s, axis=0, mode="interp")
    h = w // 2
    return coeffs, response[:h], response[w - h :]


def _savgol(x: np.ndarray, w: int, polyorder: int, deriv: int, dt_s: float) -> np.ndarray:
    """``scipy.signal.savgol_filter(x, w, polyorder, deriv, delta=dt_s, axis=0, mode="interp")`` of ``x`` (n, ...)
    with n >= w, through :func:`_savgol_operator` (the interior the same floats; the edges equal to rounding:
    tests/identify/test_measure_savgol.py)."""
    # the smoothed value (deriv 0) does not depend on the step: one operator for every clock
    coeffs, left, right = _savgol_operator(w, polyorder, deriv, float(dt_s) if deriv else 1.0)
    x = np.asarray(x, dtype=float)
    y = convolve1d(x, coeffs, axis=0, mode="constant")
    h, n = w // 2, x.shape[0]
    y[:h] = np.tensordot(left, x[:w], axes=1)
    y[n - h :] = np.tensordot(right, x[n - w :], axes=1)
    return y


def _smooth(x: np.ndarray, dt_s: float, options: MeasureOptions, *, deriv: int) -> np.ndarray:
    """Smoothed signal or its time derivative (deriv=1), rows = time, one segment."""
    n = x.shape[0]
    if options.derivative == "savgol" and n > options.polyorder + 1:
        w = _window_samples(options.window_s, dt_s, n, options.polyorder)
        if w > options.polyorder:
            return _savgol(x, w, options.polyorder, deriv, dt_s)
    if options.derivative == "triangular" and n >= 3:
        w = min(max(int(round(options.window_s / dt_s)) | 1, 3), n if n % 2 else n - 1)
        kern = triang(w)
        kern /= kern.sum()
        pad = w // 2
        xp = np.pad(x, [(pad, pad)] + [(0, 0)] * (x.ndim - 1), mode="edge")
        x = np.apply_along_axis(lambda c: np.convolve(c, kern, mode="valid"), 0, xp)
    if deriv == 0:
        return x
    # (S0-12) forward difference, last sample repeated
    d = np.diff(x, axis=0) / dt_s
    return np.concatenate([d, d[-1:]], axis=0) if len(d) else np.zeros_like(x)


def motor_lag_compensated_N(
    commanded_N: np.ndarray, dt_s: float, time_constant_s: float, *, interpolation: float = 0.0
) -> np.ndarray:
    """Actual thrusts (N, 4) of first-order motors f' = (f_cmd - f)/tau fed ``commanded_N`` (N, 4), N.

    Exact discretisation of the lag for a command that runs between samples k-1 and k as
    u(s) = u[k-1] + p (u[k] - u[k-1]) s / dt, s in [0, dt], p = ``interpolation`` (0: zero-order hold, the
    command held from each sample to the next; 1: first-order hold, linear between samples). With
    a = exp(-dt/tau) and c = 1 - (1 - a) tau / dt (the ramp's share that reaches the output within the step):
    f[k] = a f[k-1] + ((1 - a) - p c) u[k-1] + p c u[k]. Unit gain at steady state for every p; starts there.
    """
    a = float(np.exp(-dt_s / time_constant_s))
    c = interpolation * (1.0 - (1.0 - a) * time_constant_s / dt_s)
    b_coef, a_coef = [c, 1.0 - a - c], [1.0, -a]
    zi = lfilter_zi(b_coef, a_coef)[:, None] * commanded_N[0][None, :]
    out, _ = lfilter(b_coef, a_coef, commanded_N, axis=0, zi=zi)
    return out


def motor_command_for_N(delivered_N: np.ndarray, dt_s: float, time_constant_s: float) -> np.ndarray:
    """Commands (N, 4) N that make first-order motors deliver ``delivered_N`` (N, 4) N: the exact
    inverse of :func:`motor_lag_compensated_N`'s discretisation (last command repeated)."""
    a = float(np.exp(-dt_s / time_constant_s))
    cmd = (delivered_N[1:] - a * delivered_N[:-1]) / (1.0 - a)
    return np.concatenate([cmd, cmd[-1:]], axis=0) if len(cmd) else delivered_N.copy()


def measure_disturbance(
    vehicle: Vehicle,
    t_s: np.ndarray,
    quat_xyzw: np.ndarray,
    accel_mps2: np.ndarray,
    motor_thrust_N: np.ndarray,
    gyro_radps: np.ndarray,
    *,
    segment: np.ndarray | None = None,
    options: MeasureOptions = MeasureOptions(),
) -> MeasuredWrench:
    """Measured disturbance force and torque on ``vehicle`` (S0-11, S0-13 + gyroscopic term).

    Args:
        t_s: (N,) sample times, s.
        quat_xyzw: (N, 4) body-to-world attitude, scalar last.
        accel_mps2: (N, 3) accelerometer specific force in the world frame, m/s^2.
        motor_thrust_N: (N, 4) per-motor thrust, (S0-14) order, N.
        gyro_radps: (N, 3) body rates, rad/s.
        segment: (N,) contiguous-segment ids; derivatives never cross a segment boundary.
    Returns:
        :class:`MeasuredWrench`, world frame.
    """
    from proxplan.physics import mixer_matrix

    n = len(t_s)
    segment = np.zeros(n, dtype=int) if segment is None else np.asarray(segment)
    rot = Rotation.from_quat(quat_xyzw)
    J = np.asarray(vehicle.inertia_diag_kgm2)
    mix = mixer_matrix(vehicle)[1:]  # (3, 4): motor thrusts -> body torque (S0-14a-c)
    force = np.empty((n, 3))
    torque = np.empty((n, 3))
    for sid in np.unique(segment):
        idx = np.flatnonzero(segment == sid)
        t = t_s[idx]
        dt = float(np.median(np.diff(t))) if len(t) > 1 else 0.01
        thrust = motor_thrust_N[idx] * options.thrust_scale
        if options.motor_time_constant_s:
            thrust = motor_lag_compensated_N(
                thrust, dt, options.motor_time_constant_s, interpolation=options.command_interpolation
            )
        r = rot[idx]
        z_b = r.apply(np.array([0.0, 0.0, 1.0]))  # (M, 3) body z in world
        f_a = vehicle.mass_kg * accel_mps2[idx] - thrust.sum(axis=1)[:, None] * z_b  # (S0-11)
        w = gyro_radps[idx]
        tau_p = thrust @ mix.T  # body torque of the motors (S0-14)
        if options.derivative == "difference" or len(idx) < 3:  # (S0-12) raw, nothing smoothed (module docstring)
            body = J * _smooth(w, dt, options, deriv=1) + np.cross(w, J * w) - tau_p
        else:  # (S0-13) formed per sample, then ONE filter (module docstring)
            w_dot = np.gradient(w, dt, axis=0)  # mean over [t_k-1, t_k+1]; one-sided at the ends
            body = _smooth(J * w_dot + np.cross(w, J * w) - tau_p, dt, options, deriv=0)
        force[idx] = _smooth(f_a, dt, options, deriv=0)
        torque[idx] = r.apply(body)  # (S0-13): tau_a = R J w_dot (+ gyroscopic) - R tau_p
    return MeasuredWrench(force_N=force, torque_Nm=torque)


def kinematic_thrust_z_N(vehicle: Vehicle, log, *, options: MeasureOptions = MeasureOptions()) -> np.ndarray:
    """(N,) the vertical thrust the vehicle's motion calls for, m (g + dv_z/dt), N, from the log's velocity
    (motion capture, world frame) with the measurement's smoothed derivative, per contiguous segment. It
    shares no noise with the logged motor thrust or the accelerometer, so a thrust scale fitted on it is
    free of the errors-in-variables bias a regressor built on the logged thrust carries
    (:func:`proxplan.identify.data.predict`)."""
    from proxplan.physics import GRAVITY_MPS2

    n = len(log.t_s)
    segment = np.zeros(n, dtype=int) if log.segment is None else np.asarray(log.segment)
    accel_z = np.zeros(n)
    for sid in np.unique(segment):
        idx = np.flatnonzero(segment == sid)
        dt = float(np.median(np.diff(log.t_s[idx]))) if len(idx) > 1 else 0.01
        accel_z[idx] = _smooth(log.velocity_mps[idx, 2:3], dt, options, deriv=1)[:, 0]
    return vehicle.mass_kg * (GRAVITY_MPS2 + accel_z)


def smoothed_like_measurement(log, x: np.ndarray, *, options: MeasureOptions = MeasureOptions()) -> np.ndarray:
    """``x`` ((N, k) on the log's samples, any unit) smoothed per contiguous segment of ``log`` with the
    measurement's own filter (``options.window_s``, the derivative's kind): the measured wrench of
    :func:`measure_disturbance` is a smoothed quantity, so a prediction made from the logged positions
    (offsets to the sources, height above ground) is made from positions smoothed alike. Motion-capture
    noise on an offset is otherwise turned into wrench noise the measurement does not hold (near a jet's
    axis the torque is proportional to the offset: 0.5 mm of noise is a roll torque where none acts)."""
    n = len(log.t_s)
    segment = np.zeros(n, dtype=int) if log.segment is None else np.asarray(log.segment)
    out = np.array(x, dtype=float, copy=True)
    for sid in np.unique(segment):
        idx = np.flatnonzero(segment == sid)
        dt = float(np.median(np.diff(log.t_s[idx]))) if len(idx) > 1 else 0.01
        out[idx] = _smooth(out[idx], dt, options, deriv=0)
    return out


MAX_GAP_FACTOR = 2.0
"""A clock step larger than this many median steps starts a new stretch (a filter never crosses a gap), -."""


def stretches(t_s: np.ndarray) -> list[slice]:
    """Contiguous stretches of a clock (N,) (:data:`MAX_GAP_FACTOR`)."""
    if len(t_s) < 2:
        return [slice(0, len(t_s))]
    dt = np.diff(t_s)
    med = float(np.median(dt[dt > 0])) if np.any(dt > 0) else 1.0
    cuts = np.flatnonzero((dt <= 0) | (dt > MAX_GAP_FACTOR * med)) + 1
    edges = np.concatenate([[0], cuts, [len(t_s)]])
    return [slice(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:]) if b > a]


def smoothed_on_clock(t_s: np.ndarray, x: np.ndarray, *, options: MeasureOptions = MeasureOptions()) -> np.ndarray:
    """``x`` ((N, k) on the clock ``t_s`` (N,), s, any unit) smoothed with the measurement's own filter on each
    of the clock's :func:`stretches`: what :func:`smoothed_like_measurement` does on a log's segments, for a
    unit that keeps only its clock."""
    out = np.array(x, dtype=float, copy=True)
    for s in stretches(np.asarray(t_s)):
        if s.stop - s.start > 1:
            out[s] = _smooth(out[s], float(np.median(np.diff(t_s[s]))), options, deriv=0)
    return out


def measure_log(vehicle: Vehicle, log, *, options: MeasureOptions = MeasureOptions()) -> MeasuredWrench:
    """:func:`measure_disturbance` on a :class:`proxplan.identify.vehicle_log.VehicleLog`."""
    return measure_disturbance(
        vehicle,
        log.t_s,
        log.quat_xyzw,
        log.accel_mps2,
        log.motor_thrust_N,
        log.gyro_radps,
        segment=log.segment,
        options=options,
    )
