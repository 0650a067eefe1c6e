"""Fit a plan trajectory with C2-continuous piecewise 7th-order polynomials (the Crazyflie's
trajectory form), as few pieces as the position tolerance allows.

Each piece j on [b_j, b_j+1] (duration D_j, s) is written in normalised time s = t / D_j in [0, 1]
for conditioning, p_j(s) = sum_k c_jk s^k, and converted to local time t at the end
(c_jk / D_j^k). The coefficients minimise the time-weighted squared position error at
:data:`FIT_SAMPLES` points per piece plus a tiny jerk penalty (keeps the two free coefficients of
short pieces tame), subject to equality constraints: position, velocity and acceleration equal at
every joint (C2) and equal to the plan's at the start and the end. The equality-constrained least
squares problem is solved through its sparse KKT system (one sparse LU per fit; x, y, z share it).

Pieces are adapted: split the piece with the largest deviation at its middle until every
deviation is within tolerance, then drop every joint whose removal keeps the fit within tolerance.
The deviation is the plan-vs-polynomial position distance on a dense grid (step
:data:`CHECK_STEP_S`) plus half a step times the largest velocity difference, a bound on what lies
between the check points. World frame, m, s.
"""

from __future__ import annotations

from dataclasses import dataclass
from math import factorial

import numpy as np
from scipy import sparse
from scipy.sparse import linalg as sparse_linalg

from proxplan.physics import reference_error
from proxplan.planfile import (
    LEAD_SUBSTEPS,
    N_COEF,
    PolynomialTrajectory,
    VehicleTrajectory,
    predicted_path,
    resample_step,
)

FIT_SAMPLES = 48  # least-squares points per piece
CHECK_STEP_S = 0.002  # dense check grid, s
JERK_WEIGHTS = (1e-8, 1e-9, 3e-8)  # weights of the integrated squared jerk tried in turn, m^2 per (m/s^3)^2 s
DERIVATIVE_WEIGHTS = (1.0, 1e-2, 1e-4)  # position, velocity, acceleration: m^2 per (m/s)^2, per (m/s^2)^2
MERGE_PASSES = 2  # passes over the joints trying to drop each
SEARCH_FACTOR = 2  # the split phase may use up to this many times the allowed pieces before merging
MIN_PIECE_S = 0.02  # pieces are never split below this duration, s
KINEMATIC_MARGINS = (1.015, 1.015, 1.08)  # allowed excess of speed, acceleration, jerk limits (verify: 2, 2, 10 %)
OWN_MARGIN = 1.001  # where the plan itself exceeds a limit, the fit may exceed the plan's value by 0.1 %


@dataclass(frozen=True)
class PieceFit:
    """A fitted trajectory and its deviation from the plan: ``max_deviation_m`` (bound, m) overall
    and ``piece_deviation_m`` (K,) per piece; ``piece_kinematic_ratio`` (K,) see :func:`deviation`."""

    trajectory: PolynomialTrajectory
    max_deviation_m: float
    piece_deviation_m: np.ndarray
    piece_kinematic_ratio: np.ndarray

    def score(self, tolerance_m: float) -> np.ndarray:
        """Per piece (K,): the larger of deviation / tolerance and the kinematic ratio (<= 1: fine)."""
        return np.maximum(self.piece_deviation_m / tolerance_m, self.piece_kinematic_ratio)

    @property
    def max_kinematic_ratio(self) -> float:
        return float(self.piece_kinematic_ratio.max())


def _derivative_row(s: float, d: int) -> np.ndarray:
    """Row of the d-th derivative of [s^0..s^7] at s (per unit normalised time)."""
    row = np.zeros(N_COEF)
    for k in range(d, N_COEF):
        row[k] = factorial(k) / factorial(k - d) * s ** (k - d)
    return row


_ROW_AT = {(s, d): _derivative_row(s, d) for s in (0.0, 1.0) for d in range(3)}


def _jerk_gram() -> np.ndarray:
    """G with c^T G c = integral over s in [0, 1] of (d^3 p / ds^3)^2."""
    g = np.zeros((N_COEF, N_COEF))
    for a in range(3, N_COEF):
        for b in range(3, N_COEF):
            fa = factorial(a) / factorial(a - 3)
            fb = factorial(b) / factorial(b - 3)
            g[a, b] = fa * fb / (a - 3 + b - 3 + 1)
    return g


_S = np.linspace(0.0, 1.0, FIT_SAMPLES)
_BASIS = np.stack([np.array([_derivative_row(s, d) for s in _S]) for d in range(3)])  # (3, M, 8)
_JERK = _jerk_gram()


def fit_pieces(
    tr: VehicleTrajectory, breaks_s: np.ndarray, jerk_weight: float = JERK_WEIGHTS[0]
) -> PolynomialTrajectory:
    """C2 piecewise 7th-order least-squares fit of ``tr`` (position, plus lightly weighted velocity
    and acceleration) on pieces bounded by ``breaks_s`` (K + 1,), s, matching the plan's position,
    velocity and acceleration at both ends."""
    b = np.asarray(breaks_s, dtype=float)
    dur = np.diff(b)
    k_pieces = dur.size
    n = N_COEF * k_pieces
    times = (b[:-1, None] + _S[None, :] * dur[:, None]).reshape(-1)
    targets = tr.sample(times)  # p, v, a: (K * M, 3) each
    blocks = jerk_weight * _JERK[None] / dur[:, None, None] ** 5  # (K, 8, 8)
    rhs_blocks = np.zeros((k_pieces, N_COEF, 3))
    for order, target in enumerate(targets):  # derivative of order k in normalised time: / D^k
        weight = DERIVATIVE_WEIGHTS[order] * dur / FIT_SAMPLES / dur ** (2 * order)  # (K,)
        gram = _BASIS[order].T @ _BASIS[order]
        blocks += weight[:, None, None] * gram[None]
        rhs_weight = (weight * dur**order)[:, None, None]  # the right-hand side carries one 1/D^k
        rhs_blocks += rhs_weight * np.einsum("mk,jmd->jkd", _BASIS[order], target.reshape(k_pieces, FIT_SAMPLES, 3))
    hess = sparse.block_diag(list(blocks), format="csr")
    rhs = rhs_blocks.reshape(n, 3)
    con_rows: list[int] = []
    con_cols: list[int] = []
    con_vals: list[float] = []
    values: list[np.ndarray] = []

    def constraint(entries: list[tuple[int, np.ndarray]], value: np.ndarray) -> None:
        row = len(values)
        for first, coefs in entries:
            con_rows.extend([row] * N_COEF)
            con_cols.extend(range(first, first + N_COEF))
            con_vals.extend(coefs)
        values.append(value)

    ends = tr.sample(np.array([b[0], b[-1]]))
    for d_ord in range(3):
        constraint([(0, _derivative_row(0.0, d_ord) / dur[0] ** d_ord)], ends[d_ord][0])
        constraint([(n - N_COEF, _derivative_row(1.0, d_ord) / dur[-1] ** d_ord)], ends[d_ord][1])
    for j in range(k_pieces - 1):
        for d_ord in range(3):
            left = (N_COEF * j, _derivative_row(1.0, d_ord) / dur[j] ** d_ord)
            right = (N_COEF * (j + 1), -_derivative_row(0.0, d_ord) / dur[j + 1] ** d_ord)
            constraint([left, right], np.zeros(3))
    con = sparse.csr_matrix((con_vals, (con_rows, con_cols)), shape=(len(values), n))
    kkt = sparse.bmat([[hess, con.T], [con, None]], format="csc")
    sol = sparse_linalg.splu(kkt).solve(np.vstack([rhs, np.array(values)]))[:n]  # (n, 3)
    coef_s = sol.reshape(k_pieces, N_COEF, 3).transpose(0, 2, 1)  # (K, 3, 8) in normalised time
    scale = dur[:, None] ** -np.arange(N_COEF)[None, :]  # c_t[k] = c_s[k] / D^k
    coef = np.zeros((k_pieces, 4, N_COEF))
    coef[:, :3, :] = coef_s * scale[:, None, :]
    return PolynomialTrajectory(dur, coef, float(b[0]))


class FitTarget:
    """One vehicle's reference on [t0_s, t1_s] sampled once: on the dense check grid (step <=
    :data:`CHECK_STEP_S`, s) for position, speed and acceleration, and on the grid the export is
    re-read and verified on (:func:`proxplan.planfile.resample_step`) for jerk, measured as the verifier
    does (acceleration difference over one step). ``allowed_*`` hold, per check point, the larger of
    the limit times :data:`KINEMATIC_MARGINS` and the own value times :data:`OWN_MARGIN`
    (``limits``: speed m/s, acceleration m/s^2, jerk m/s^3, or None).

    With ``flown`` the reference is an upload with a drag lead (it exceeds the limits by design;
    sampled :data:`proxplan.planfile.LEAD_SUBSTEPS` times finer than the plan, whose grid the jerk is
    checked on):
    speed, acceleration and jerk are then those of the vehicle's predicted flight
    (:func:`proxplan.planfile.predicted_path`, what ``proxplan verify`` checks on an export): the
    target's own flight plus the flight of the fit's difference from the target, from rest at t0_s
    (where a fit matches the target's position, velocity and acceleration)."""

    def __init__(
        self,
        tr: VehicleTrajectory,
        t0_s: float,
        t1_s: float,
        limits: tuple[float, float, float] | None,
        tolerance_m: float = 1.0,
        flown: bool = False,
    ):
        self.tr = tr
        self.tolerance_m = tolerance_m
        n = max(2, int(np.ceil((t1_s - t0_s) / CHECK_STEP_S)) + 1)
        self.t = np.linspace(t0_s, t1_s, n)
        self.step_s = float(self.t[1] - self.t[0])
        self.p, self.v, self.a = tr.sample(self.t)
        self.limits = limits
        self.flown = flown
        if limits is None:
            return
        self.kt = self.t  # where speed and acceleration are checked
        kin_v, kin_a = self.v, self.a
        if flown:  # on the reference's own grid, where proxplan.planfile.read_export predicts the flight
            inside = (tr.t_s >= t0_s - 1e-9) & (tr.t_s <= t1_s + 1e-9)
            jerk = tr.jerk_at(tr.t_s)
            flight = predicted_path(tr.t_s, tr.position_m, tr.velocity_mps, tr.acceleration_mps2, jerk, tr.vehicle)
            self.kt = tr.t_s[inside]
            self.ref = (tr.velocity_mps[inside], tr.acceleration_mps2[inside], jerk[inside])
            self.flight_v, self.flight_a = flight[1][inside], flight[2][inside]
            kin_v, kin_a = self.flight_v, self.flight_a
        margin = np.array(KINEMATIC_MARGINS)
        own_va = np.stack([np.linalg.norm(kin_v, axis=1), np.linalg.norm(kin_a, axis=1)])
        self.allowed_va = np.maximum(OWN_MARGIN * own_va, (margin * np.array(limits))[:2, None])
        step = float(tr.t_s[1] - tr.t_s[0]) * (LEAD_SUBSTEPS if flown else 1)  # a reference is finer than its plan
        self.jerk_step_s = resample_step(step)
        k0 = int(np.ceil(t0_s / self.jerk_step_s - 1e-9))
        k1 = int(np.floor(t1_s / self.jerk_step_s + 1e-9))
        self.tj = np.arange(k0, k1 + 1) * self.jerk_step_s
        if self.tj.size == 0:
            self.tj = np.array([t0_s])
        both = np.concatenate([self.tj, self.tj + self.jerk_step_s])
        self.a_j = _interp_rows(both, self.kt, kin_a) if flown else tr.sample(both)[2]
        self.allowed_j = np.maximum(OWN_MARGIN * self._jerk(self.a_j), margin[2] * limits[2])

    def _jerk(self, a_both: np.ndarray) -> np.ndarray:
        n = self.tj.size
        return np.linalg.norm(a_both[n:] - a_both[:n], axis=1) / self.jerk_step_s

    def _kinematics(self, traj: PolynomialTrajectory, fit_v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Velocity and acceleration (M, 3) at ``kt`` whose limits are checked: the fit's own, or
        with ``flown`` its predicted flight (class docstring)."""
        if not self.flown:
            return fit_v, traj.evaluate(self.t, 2)[:, :3]
        rv, ra, rj = self.ref
        dv, da, dj = (traj.evaluate(self.kt, d)[:, :3] - r for d, r in ((1, rv), (2, ra), (3, rj)))
        err = reference_error(self.kt, dv, da, dj, self.tr.vehicle)
        return self.flight_v + dv - err.rate, self.flight_a + da - err.accel

    def measure(self, traj: PolynomialTrajectory) -> PieceFit:
        """Deviation and kinematic ratio of ``traj`` per piece (see :func:`deviation`)."""
        piece = np.clip(np.searchsorted(traj.joints_s, self.t, side="right") - 1, 0, traj.n_pieces - 1)
        dp = np.linalg.norm(traj.evaluate(self.t)[:, :3] - self.p, axis=1)
        fit_v = traj.evaluate(self.t, 1)[:, :3]
        bound = dp + 0.5 * self.step_s * np.linalg.norm(fit_v - self.v, axis=1)
        per_piece = np.zeros(traj.n_pieces)
        np.maximum.at(per_piece, piece, bound)
        ratio = np.zeros(traj.n_pieces)
        if self.limits is not None:
            kin_v, kin_a = self._kinematics(traj, fit_v)
            va = np.stack([np.linalg.norm(kin_v, axis=1), np.linalg.norm(kin_a, axis=1)])
            piece_k = np.clip(np.searchsorted(traj.joints_s, self.kt, side="right") - 1, 0, traj.n_pieces - 1)
            np.maximum.at(ratio, piece_k, (va / self.allowed_va).max(axis=0))
            both = np.concatenate([self.tj, self.tj + self.jerk_step_s])
            a_j = _interp_rows(both, self.kt, kin_a) if self.flown else traj.evaluate(both, 2)[:, :3]
            after = both > traj.end_time_s + 1e-9  # the plan's (rest, or the next upload, which starts in its state)
            a_j[after] = self.a_j[after]
            piece_j = np.clip(np.searchsorted(traj.joints_s, self.tj, side="right") - 1, 0, traj.n_pieces - 1)
            np.maximum.at(ratio, piece_j, self._jerk(a_j) / self.allowed_j)
        return PieceFit(traj, float(per_piece.max()), per_piece, ratio)


def _interp_rows(t_s: np.ndarray, grid_s: np.ndarray, values: np.ndarray) -> np.ndarray:
    """``values`` (K, 3) on ``grid_s`` (K,) linearly interpolated at ``t_s`` (M,), held outside."""
    return np.column_stack([np.interp(t_s, grid_s, values[:, d]) for d in range(values.shape[1])])


def deviation(
    tr: VehicleTrajectory, traj: PolynomialTrajectory, limits: tuple[float, float, float] | None = None
) -> PieceFit:
    """How well ``traj`` reproduces ``tr``: per piece a bound on the position distance, m (the
    distance on a grid of step <= :data:`CHECK_STEP_S` plus half a step times the velocity
    difference), and the largest ratio of the polynomials' speed, acceleration and jerk norms to
    what is allowed (<= 1: fine): the larger of ``limits`` (speed m/s, acceleration m/s^2, jerk
    m/s^3) times :data:`KINEMATIC_MARGINS` and the plan's own value there times :data:`OWN_MARGIN`
    (the export adds no excess the plan does not have, beyond rounding). Ratios are 0 without ``limits``."""
    return FitTarget(tr, traj.start_time_s, traj.end_time_s, limits).measure(traj)


def adaptive_fit(
    tr: VehicleTrajectory,
    *,
    tolerance_m: float,
    max_pieces: int | None,
    t0_s: float,
    t1_s: float,
    limits: tuple[float, float, float] | None = None,
    flown: bool = False,
) -> PieceFit:
    """Fewest-pieces fit of ``tr`` on [t0_s, t1_s], s, within ``tolerance_m``, m, and (with
    ``limits``) within the kinematic allowance (see :func:`deviation`).

    Splits every piece out of tolerance (and its longer neighbours, which C2 couples to it) at the
    middle (moved to the nearest plan sample time, where the plan's own pieces join) until every piece is fine (or :data:`SEARCH_FACTOR` x ``max_pieces`` is reached, or
    pieces get shorter than :data:`MIN_PIECE_S`), then removes every joint it can without leaving
    the tolerance. Tries the jerk penalties :data:`JERK_WEIGHTS` in turn until one fits in
    ``max_pieces``. The result may be out of tolerance or have too many pieces: callers check
    :func:`fit_ok`."""
    target = FitTarget(tr, t0_s, t1_s, limits, tolerance_m, flown)
    cap = max_pieces if max_pieces is not None else 10**6
    best = None
    for weight in JERK_WEIGHTS:  # the jerk penalty changes which joints suffice: keep the fewest pieces
        fit = _refine(tr, target, tolerance_m, cap, weight)
        ok = fit_ok(fit, tolerance_m, cap)
        if best is None or (
            ok and (not fit_ok(best, tolerance_m, cap) or fit.trajectory.n_pieces < best.trajectory.n_pieces)
        ):
            best = fit
        if ok and fit.trajectory.n_pieces <= cap:
            break
    assert best is not None
    return best


def _refine(tr: VehicleTrajectory, target: FitTarget, tolerance_m: float, cap: int, weight: float) -> PieceFit:
    t0_s, t1_s = float(target.t[0]), float(target.t[-1])
    breaks = np.array([t0_s, t1_s])
    best = target.measure(fit_pieces(tr, breaks, weight))
    while not fit_ok(best, tolerance_m) and breaks.size - 1 < SEARCH_FACTOR * cap:
        bad = best.score(tolerance_m) > 1.0
        dur = np.diff(breaks)
        split = bad.copy()  # a bad piece and its longer neighbours (C2 couples them)
        split[:-1] |= bad[1:] & (dur[:-1] > dur[1:])
        split[1:] |= bad[:-1] & (dur[1:] > dur[:-1])
        split &= dur >= 2 * MIN_PIECE_S
        if not split.any():
            break
        middles = 0.5 * (breaks[:-1] + breaks[1:])[split]
        snapped = _snap(middles, tr.t_s)
        inside = (snapped > breaks[:-1][split] + MIN_PIECE_S) & (snapped < breaks[1:][split] - MIN_PIECE_S)
        breaks = np.sort(np.concatenate([breaks, np.where(inside, snapped, middles)]))
        best = target.measure(fit_pieces(tr, breaks, weight))
    if not fit_ok(best, tolerance_m) or breaks.size - 1 > SEARCH_FACTOR * cap:
        return best
    for _ in range(MERGE_PASSES):  # merge: drop joints that are not needed
        changed = False
        i = 1
        while i < breaks.size - 1:
            trial = np.delete(breaks, i)
            fit = target.measure(fit_pieces(tr, trial, weight))
            if fit_ok(fit, tolerance_m):
                breaks, best, changed = trial, fit, True
            else:
                i += 1
        if not changed:
            break
    return best


def _snap(t_s: np.ndarray, grid_s: np.ndarray) -> np.ndarray:
    """Each time moved to the nearest plan sample time (where the plan's own pieces join), s."""
    k = np.clip(np.searchsorted(grid_s, t_s), 1, grid_s.size - 1)
    left, right = grid_s[k - 1], grid_s[k]
    return np.where(t_s - left <= right - t_s, left, right)


def fit_ok(fit: PieceFit, tolerance_m: float, max_pieces: int | None = None) -> bool:
    """Within the position tolerance and the kinematic allowance everywhere (and ``max_pieces``)."""
    within = max_pieces is None or fit.trajectory.n_pieces <= max_pieces
    return within and bool(fit.score(tolerance_m).max() <= 1.0)


def fit_uniform(
    tr: VehicleTrajectory,
    pieces: int,
    limits: tuple[float, float, float] | None,
    tolerance_m: float,
    flown: bool = False,
) -> PieceFit:
    """The fit on ``pieces`` equal pieces over the whole plan (what that many pieces reach)."""
    t0, t1 = float(tr.t_s[0]), float(tr.t_s[-1])
    target = FitTarget(tr, t0, t1, limits, tolerance_m, flown)
    return target.measure(fit_pieces(tr, np.linspace(t0, t1, pieces + 1)))
