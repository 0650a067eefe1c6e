"""A near time-optimal, jerk-limited time law along a quadratic path (issue 37 items 1 and 5):
:func:`quadratic_law`, used by :class:`~proxplan.planner.timing.arcs.ArcMove`.

The path is p(sigma) = p0 + sigma D + 4 sigma (1 - sigma) w, sigma in [0, 1] (world frame, m), so
p' = D + 4 (1 - 2 sigma) w, p'' = -8 w and p''' = 0; flown along sigma(t),

    v = p' sigma',  a = p'' sigma'^2 + p' sigma'',  j = 3 p'' sigma' sigma'' + p' sigma''',

and the vehicle's limits bound the NORMS |v| <= V, |a| <= A, |j| <= J (what the verifier checks).

*The law.* sigma(t) goes from rest at 0 to rest at 1 and is point-symmetric about its middle
(sigma(T - t) = 1 - sigma(t)), so the vehicle passes p(1/2) at half time. On the first half, in
normalised time (T = 1), sigma''' is constant on each of :data:`HALF_PIECES` equal intervals (a
vector u); sigma, sigma', sigma'' are then linear in u, and the middle's conditions sigma(1/2) = 1/2,
sigma''(1/2) = 0 two linear equalities. Flown in time c (the law stretched by c), the norms divide by c,
c^2 and c^3, so the least c for a law is

    c(u) = max(max|v_n| / V, sqrt(max|a_n| / A), cbrt(max|j_n| / J))   (n: normalised).

*Near-optimal, not optimal.* ``scipy.optimize.minimize`` (SLSQP, analytic gradients) minimises c over
u and the stretch tau with |v_n|^2 <= (f V tau)^2, |a_n|^2 <= (f A tau^2)^2, |j_n|^2 <= (f J tau^3)^2 at
:data:`FIT_SAMPLES` instants per interval (both halves), starting from a fixed symmetric law
(:data:`START_JERK`). The problem is not convex and the law is piecewise-cubic: the result is a
feasible law, not proven optimal. The gap is measured against the time-optimal law under speed and
acceleration alone (a lower bound: every jerk-limited law obeys those two), see ``benchmarks/why_by_type.py``.

*Exact against the limits.* Whatever the optimiser returns (or, if it fails, the starting law), the
duration is c of that law evaluated at :data:`CHECK_SAMPLES` instants per interval with the exact
formulas above (sigma''' is exact: piecewise constant), kept within :data:`LIMIT_FRACTION` of the
limits, then rounded UP to whole grid steps (a further uniform slow-down: the norms only fall). The
same inputs give the same law (SLSQP is deterministic); laws are cached by shape.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from proxplan.physics import KinematicLimits, one_blas_thread

# the norms are kept within this fraction of the vehicle's limits (the same margin as round 21S's
# uniform arc timing: the verifier allows 2 % on speed and acceleration and 10 % on jerk, and checks
# positions between plan samples, so the plan stays off that edge)
LIMIT_FRACTION = 0.97
# intervals of constant sigma''' on the law's first half, and the instants per interval at which the
# optimiser's constraints are imposed (plus each interval's ends): on 15 arcs of grid-64 (0.6 / 0.85 / 1.2 m
# chords, 0.25-1 reach aside) 12 x 2 gives the same grid steps as 16 x 2 within one step (two arcs) at a
# sixth of its CPU; 8 x 3 is up to one step longer on 5 (round 27S)
HALF_PIECES = 12
FIT_SAMPLES = 2
CHECK_SAMPLES = 64  # instants per interval at which the final law's norms are evaluated exactly
OPT_MAX_ITER = 300  # SLSQP iterations (a count: the law is the same on any machine); ~90 are used
# the law is optimised once per shape rounded to this (m; its stretch is then the true shape's, exact):
# circle-256 by type asks 328 shapes that differ by float noise only (12 at 1 mm or at 5 mm; round 27S)
SHAPE_QUANTUM_M = 1e-3
FLOOR_SAMPLES = 4000  # path samples of the speed-and-acceleration floor's forward-backward pass
OPT_FTOL = 1e-9  # SLSQP's tolerance on the stretch (normalised time, s per unit duration)
# the starting law's sigma''' on the first half's quarters of intervals, before the middle's two
# equalities are imposed by least squares: +, -, -, + like a jerk-limited rest-to-rest move
START_JERK = (1.0, -1.0, -1.0, 1.0)

__all__ = [
    "CHECK_SAMPLES",
    "FIT_SAMPLES",
    "HALF_PIECES",
    "LIMIT_FRACTION",
    "OPT_FTOL",
    "OPT_MAX_ITER",
    "FLOOR_SAMPLES",
    "SHAPE_QUANTUM_M",
    "START_JERK",
    "PathLaw",
    "quadratic_law",
    "speed_accel_floor_s",
]


@lru_cache(maxsize=8)
def _maps(pieces: int, per_piece: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Linear maps u -> (sigma, sigma', sigma'', sigma''') at ``per_piece + 1`` instants of each interval
    of the first half (normalised time), shape (4, pieces (per_piece + 1), pieces); the knots' states
    (pieces + 1, 3, pieces); and the instants (normalised time)."""
    h = 0.5 / pieces
    knots = np.zeros((pieces + 1, 3, pieces))
    for k in range(pieces):
        s, sd, sdd = knots[k]
        knots[k + 1] = (s + sd * h + sdd * h * h / 2.0, sd + sdd * h, sdd)
        knots[k + 1, :, k] += (h**3 / 6.0, h * h / 2.0, h)
    rows, times = [], []
    for k in range(pieces):
        s, sd, sdd = knots[k]
        e = np.zeros(pieces)
        e[k] = 1.0
        for r in range(per_piece + 1):
            d = r * h / per_piece
            rows.append(
                (s + sd * d + sdd * d * d / 2.0 + e * d**3 / 6.0, sd + sdd * d + e * d * d / 2.0, sdd + e * d, e)
            )
            times.append(k * h + d)
    return np.array(rows).transpose(1, 0, 2), knots, np.array(times)


def _states(u: np.ndarray, maps: np.ndarray, mirror: bool):
    """sigma, sigma', sigma'', sigma''' at the sampled instants of the first half and, with ``mirror``,
    of the second (mirrored)."""
    s, sd, sdd, sddd = maps @ u
    if not mirror:
        return s, sd, sdd, sddd
    return (
        np.concatenate([s, 1.0 - s]),
        np.concatenate([sd, sd]),
        np.concatenate([sdd, -sdd]),
        np.concatenate([sddd, sddd]),
    )


def _norms2(u: np.ndarray, maps: np.ndarray, delta: np.ndarray, bulge: np.ndarray, mirror: bool = True):
    """Squared norms of v, a, j (normalised time) at the sampled instants (``mirror``: of both halves, else
    of the first), and what their gradients need."""
    s, sd, sdd, sddd = _states(u, maps, mirror)
    dp = delta[None] + (4.0 * (1.0 - 2.0 * s))[:, None] * bulge[None]
    ddp = -8.0 * bulge
    v = dp * sd[:, None]
    a = ddp[None] * (sd * sd)[:, None] + dp * sdd[:, None]
    j = 3.0 * ddp[None] * (sd * sdd)[:, None] + dp * sddd[:, None]
    return (v * v).sum(1), (a * a).sum(1), (j * j).sum(1), (s, sd, sdd, sddd, dp, v, a, j)


def _grads(u: np.ndarray, maps: np.ndarray, delta: np.ndarray, bulge: np.ndarray, mirror: bool = True, norms=None):
    """Gradients over u of the squared norms of v, a, j at the sampled instants (chain rule, see module);
    ``norms``: :func:`_norms2` of the same arguments where already computed."""
    _, _, _, (s, sd, sdd, sddd, dp, v, a, j) = norms if norms is not None else _norms2(u, maps, delta, bulge, mirror)
    m0, m1, m2, m3 = maps
    if mirror:  # d sigma / du, ... on both halves
        ds, dsd, dsdd, dsddd = np.vstack([m0, -m0]), np.vstack([m1, m1]), np.vstack([m2, -m2]), np.vstack([m3, m3])
    else:
        ds, dsd, dsdd, dsddd = m0, m1, m2, m3
    ddp = -8.0 * bulge
    gv = 2.0 * ((v @ ddp) * sd)[:, None] * ds + 2.0 * (v * dp).sum(1)[:, None] * dsd
    ga = 2.0 * (
        ((a @ ddp) * 2.0 * sd)[:, None] * dsd + ((a @ ddp) * sdd)[:, None] * ds + (a * dp).sum(1)[:, None] * dsdd
    )
    jd = j @ ddp
    gj = 2.0 * (
        (3.0 * jd)[:, None] * (sdd[:, None] * dsd + sd[:, None] * dsdd)
        + (jd * sddd)[:, None] * ds
        + (j * dp).sum(1)[:, None] * dsddd
    )
    return gv, ga, gj


def _least_stretch(u: np.ndarray, delta: np.ndarray, bulge: np.ndarray, limits: KinematicLimits) -> float:
    """c(u) (see module) at :data:`CHECK_SAMPLES` instants per interval, within :data:`LIMIT_FRACTION`."""
    maps, _, _ = _maps(len(u), CHECK_SAMPLES)
    v2, a2, j2, _ = _norms2(u, maps, delta, bulge)
    f = LIMIT_FRACTION
    return max(
        math.sqrt(float(v2.max())) / (f * limits.max_speed_mps),
        math.sqrt(math.sqrt(float(a2.max())) / (f * limits.max_accel_mps2)),
        (math.sqrt(float(j2.max())) / (f * limits.max_jerk_mps3)) ** (1.0 / 3.0),
    )


@one_blas_thread  # small products in a loop: OpenBLAS' threads cost 30x here on the shared host (27S)
def _optimise(delta: np.ndarray, bulge: np.ndarray, limits: KinematicLimits) -> np.ndarray:
    """The law u minimising the stretch (see module); the starting law where SLSQP fails or is not better."""
    from scipy.optimize import minimize

    n = HALF_PIECES
    _, knots, _ = _maps(n, FIT_SAMPLES)
    eq = np.array([knots[n, 0], knots[n, 2]])
    rhs = np.array([0.5, 0.0])
    u0 = np.asarray(START_JERK, dtype=float)[np.arange(n) * len(START_JERK) // n]
    u0 = u0 + np.linalg.lstsq(eq, rhs - eq @ u0, rcond=None)[0]
    maps, _, _ = _maps(n, FIT_SAMPLES)
    f = LIMIT_FRACTION
    # a bulge square to the chord (every joint move's): |p'| and the angle between p' and p'' are the same
    # at sigma and 1 - sigma, so the mirrored half's norms equal the first half's: only those are imposed
    mirror = abs(float(np.dot(delta, bulge))) > 1e-12 * float(np.dot(delta, delta))
    kv, ka, kj = ((f * x) ** -2 for x in (limits.max_speed_mps, limits.max_accel_mps2, limits.max_jerk_mps3))

    last_norms: dict[bytes, tuple] = {}  # the norms at the last point asked (SLSQP asks cons, then its Jacobian)

    def norms(z):
        key = z.tobytes()
        if key not in last_norms:
            last_norms.clear()
            last_norms[key] = _norms2(z[:-1], maps, delta, bulge, mirror)
        return last_norms[key]

    def cons(z):
        v2, a2, j2, _ = norms(z)
        t = z[-1]
        return np.concatenate([t * t - kv * v2, t**4 - ka * a2, t**6 - kj * j2])

    def cons_jac(z):
        gv, ga, gj = _grads(z[:-1], maps, delta, bulge, mirror, norms(z))
        t = z[-1]
        m = len(gv)
        col = np.concatenate([np.full(m, 2.0 * t), np.full(m, 4.0 * t**3), np.full(m, 6.0 * t**5)])
        return np.hstack([-np.vstack([kv * gv, ka * ga, kj * gj]), col[:, None]])

    start = _least_stretch(u0, delta, bulge, limits)
    last = np.zeros(n + 1)
    last[-1] = 1.0
    res = minimize(
        lambda z: z[-1],
        np.append(u0, start),
        jac=lambda z: last,
        method="SLSQP",
        constraints=[
            {"type": "ineq", "fun": cons, "jac": cons_jac},
            {"type": "eq", "fun": lambda z: eq @ z[:-1] - rhs, "jac": lambda z: np.hstack([eq, np.zeros((2, 1))])},
        ],
        options={"maxiter": OPT_MAX_ITER, "ftol": OPT_FTOL},
    )
    u = res.x[:-1]
    ok = bool(np.all(np.isfinite(u))) and float(np.abs(eq @ u - rhs).max()) < 1e-9
    if ok and _least_stretch(u, delta, bulge, limits) < start:
        return u
    return u0


@dataclass(frozen=True)
class PathLaw:
    """sigma(t) from rest at 0 to rest at 1 in ``steps`` grid steps of ``dt_s`` (s), see module."""

    half_jerk: np.ndarray  # (HALF_PIECES,) sigma''' per interval of the first half, normalised time (T = 1)
    steps: int
    dt_s: float

    @property
    def duration_s(self) -> float:
        return self.steps * self.dt_s

    def states(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """sigma (-), sigma' (1/s) and sigma'' (1/s^2) at the times ``t_s`` (s) after the start (rest outside)."""
        T = self.duration_s
        tn = np.clip(np.asarray(t_s, dtype=float) / T, 0.0, 1.0)
        mirrored = tn > 0.5
        x = np.where(mirrored, 1.0 - tn, tn)
        n = len(self.half_jerk)
        h = 0.5 / n
        k = np.minimum((x / h).astype(int), n - 1)
        _, knots, _ = _maps(n, FIT_SAMPLES)
        at_knots = knots @ self.half_jerk  # (n + 1, 3): sigma, sigma', sigma'' at the knots
        s, sd, sdd = at_knots[k].T
        d = x - k * h
        u = self.half_jerk[k]
        s, sd, sdd = s + sd * d + sdd * d * d / 2.0 + u * d**3 / 6.0, sd + sdd * d + u * d * d / 2.0, sdd + u * d
        s = np.where(mirrored, 1.0 - s, s)
        sdd = np.where(mirrored, -sdd, sdd)
        return s, sd / T, sdd / (T * T)

    def at(self, t_s: float) -> tuple[float, float, float]:
        """sigma (-), sigma' (1/s) and sigma'' (1/s^2) at ``t_s`` (s) after the start (rest outside)."""
        if t_s <= 0.0:
            return 0.0, 0.0, 0.0
        if t_s >= self.duration_s:
            return 1.0, 0.0, 0.0
        s, sd, sdd = self.states(np.array([t_s]))
        return float(s[0]), float(sd[0]), float(sdd[0])

    def sigma_grid(self) -> np.ndarray:
        """sigma at every grid time 0, dt, ..., duration (steps + 1,)."""
        out = self.states(np.arange(self.steps + 1) * self.dt_s)[0]
        out[0], out[-1] = 0.0, 1.0
        return out


def _shape(chord_m: float, bulge_m: float, along_m: float) -> tuple[np.ndarray, np.ndarray]:
    """The chord and bulge vectors (m) of a shape (a rotation leaves the norms unchanged)."""
    return np.array([chord_m, 0.0, 0.0]), np.array([along_m, math.sqrt(max(bulge_m**2 - along_m**2, 0.0)), 0.0])


@lru_cache(maxsize=4096)
def _shape_law(chord_q: int, bulge_q: int, along_q: int, limits: KinematicLimits) -> np.ndarray:
    """The optimised u of the shape given in units of :data:`SHAPE_QUANTUM_M` (read-only)."""
    q = SHAPE_QUANTUM_M
    u = _optimise(*_shape(chord_q * q, bulge_q * q, along_q * q), limits)
    u.setflags(write=False)
    return u


@lru_cache(maxsize=4096)
def _cached_law(chord_m: float, bulge_m: float, along_m: float, limits: KinematicLimits, dt_s: float) -> PathLaw:
    """:func:`quadratic_law` of a chord of ``chord_m`` and a bulge of norm ``bulge_m`` whose component
    along the chord is ``along_m`` (m): the norms depend on nothing else (a rotation leaves them unchanged).
    The law is optimised for the shape rounded to :data:`SHAPE_QUANTUM_M`; its stretch (so its steps) is
    that of the shape itself, exact."""
    q = SHAPE_QUANTUM_M
    u = _shape_law(max(1, round(chord_m / q)), round(bulge_m / q), round(along_m / q), limits)
    c = _least_stretch(u, *_shape(chord_m, bulge_m, along_m), limits)
    return PathLaw(u, max(1, int(math.ceil(c / dt_s - 1e-9))), dt_s)


def quadratic_law(
    p0_m: np.ndarray, p1_m: np.ndarray, bulge_m: np.ndarray, limits: KinematicLimits, dt_s: float
) -> PathLaw:
    """The law (see module) along p0 -> p1 (m) bulging by ``bulge_m`` (m) within ``limits``, on the
    ``dt_s`` grid (s)."""
    delta = np.asarray(p1_m, dtype=float) - np.asarray(p0_m, dtype=float)
    bulge = np.asarray(bulge_m, dtype=float)
    chord = float(np.linalg.norm(delta))
    if chord <= 0.0:
        raise ValueError("a law needs distinct ends")
    along = float(np.dot(bulge, delta)) / chord
    return _cached_law(round(chord, 9), round(float(np.linalg.norm(bulge)), 9), round(along, 9), limits, dt_s)


def speed_accel_floor_s(delta_m: np.ndarray, bulge_m: np.ndarray, limits: KinematicLimits) -> float:
    """A lower bound on the time (s) of any rest-to-rest flight along the path of the module (chord
    ``delta_m``, bulge ``bulge_m``, m) within ``limits``: the time-optimal one under the speed and
    acceleration norms alone (the jerk ignored), by the classic forward-backward pass over
    :data:`FLOOR_SAMPLES` path samples (Bobrow / TOPP: with x = sigma'^2, |p'|^2 x <= V^2 and
    |p'' x + p' sigma''| <= A bound sigma'' = x' / 2 at each sample; the greatest x under the two
    passes, integrated as dt = 2 dsigma / (sigma'_k + sigma'_{k+1})). For measuring the law's gap
    (``benchmarks/why_by_type.py``); the sampling makes it approximate to ~1e-3 s."""
    n = FLOOR_SAMPLES
    s = np.linspace(0.0, 1.0, n + 1)
    h = 1.0 / n
    delta, bulge = np.asarray(delta_m, dtype=float), np.asarray(bulge_m, dtype=float)
    dp = delta[None] + (4.0 * (1.0 - 2.0 * s))[:, None] * bulge[None]
    ddp = -8.0 * bulge
    n1 = (dp * dp).sum(1)
    b1 = dp @ ddp  # p' . p''
    n2 = float(ddp @ ddp)
    perp = np.sqrt(np.maximum(n2 - b1 * b1 / n1, 0.0))  # |p''| square to p'
    V, A = limits.max_speed_mps, limits.max_accel_mps2
    x_max = np.minimum(V * V / n1, np.where(perp > 1e-12, A / np.maximum(perp, 1e-12), np.inf))

    def roots(k: int, x: float) -> tuple[float, float] | None:  # the sigma'' range at sample k
        b, c = x * b1[k], x * x * n2 - A * A
        disc = b * b - n1[k] * c
        if disc < 0.0:
            return None
        r = math.sqrt(disc)
        return (-b - r) / n1[k], (-b + r) / n1[k]

    fw = np.zeros(n + 1)
    for k in range(n):
        got = roots(k, fw[k])
        fw[k + 1] = x_max[k + 1] if got is None else min(x_max[k + 1], fw[k] + 2.0 * got[1] * h)
    bw = np.zeros(n + 1)
    for k in range(n, 0, -1):
        got = roots(k, bw[k])
        bw[k - 1] = x_max[k - 1] if got is None else min(x_max[k - 1], bw[k] - 2.0 * got[0] * h)
    sd = np.sqrt(np.maximum(np.minimum(fw, bw), 0.0))
    return float(np.sum(2.0 * h / np.maximum(sd[1:] + sd[:-1], 1e-12)))
