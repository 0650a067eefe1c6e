"""Several sources above one target: shielding of an upper jet by the rotors of a lower source.

Seed paper 000 models one source above one target (S0-1..S0-8). With a stack (source U above
source M above target B), adding U's and M's wrenches on B assumes U's jet reaches B as if M were
not there. It does not: M's rotors ingest the part of U's jet that falls on their disks (M's
controller holds M's thrust at its hover value, so what M blows down is M's own jet of thrust T_M,
already in M's term), M's frame stops the part that hits it (that momentum is the frame drag
S0-3 on M), and only the part of U's jet that misses M's disks and frame flows on to B.

Shielding model (one parameter). The momentum flux of U's jet through a horizontal plane at M's
rotor height is ``rho * integral V_U^2 dA``; with the Gaussian profile of (S0-2),
``V_U = V_max exp(-c_rad r^2 / a^2)`` (a = dz - z0, S0-1), the plane's total is
``rho V_max^2 pi a^2 / (2 c_rad)`` and the share through M's four disks and its frame is

    phi_UM = (2 c_rad / (pi a^2)) * (A_p,M sum_i mean_{disk i} exp(-2 c_rad r^2 / a^2)
                                     + sum_e A_e exp(-2 c_rad r_e^2 / a^2))              in [0, 1]

(disk means by the quadrature of :func:`proxplan.physics.geometry.disk_samples`, frame elements e of
area A_e by :func:`proxplan.physics.geometry.frame_elements`; a narrow near-field jet on the axis
passes between the rotors and is stopped by the hub). U's wrench on B is
multiplied by the share of its flux that is not ingested by any source between U and B,

    s_U = prod_{M between U and B} (1 - eta * phi_UM),

clipped at 0, with ``eta`` (``ModelOptions.stack_shielding``, -, in [0, :data:`MAX_STACK_SHIELDING`])
the flux taken out of U's jet per unit of flux M intercepts: 1 = every intercepted stream tube is
replaced by M's own jet (the default, by the argument above), 0 = no shielding (the per-pair sum,
S0's superposition of wrenches), above 1 = M's wake also deflects or entrains the part of U's jet
around its footprint (the footprint acts larger than the vehicle). ``eta`` is
calibrated on flight logs by ``proxplan identify``. With one source above the target every factor is
1 and the model is S0's exactly; factors never exceed 1, so the per-pair sum is an upper bound of the
stack's disturbance (the planner's per-pair bounds stay conservative).

"Between": M is below U (its rotor plane more than 1e-6 m lower) and above the target.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from functools import lru_cache

import numpy as np

from proxplan.physics.geometry import Discretisation, disk_samples, frame_elements
from proxplan.physics.vehicles import Vehicle
from proxplan.physics.velocity_field import axial_distance_m

_MIN_DZ_M = 1e-6
MAX_STACK_SHIELDING = 3.0
"""Largest eta accepted, -: M's footprint acting at most three times its area."""
DEFAULT_DISCRETISATION = Discretisation()


@lru_cache(maxsize=64)
def _footprint(vehicle: Vehicle, disc: Discretisation) -> tuple[np.ndarray, np.ndarray]:
    """Horizontal points (K, 2), m, and the area each stands for (K,), m^2: disk quadrature points
    (A_p / P each) then frame elements."""
    d = disk_samples(vehicle, disc)
    fr = frame_elements(vehicle, disc)
    disk_xy = d.flat_position_m[:, :2]
    disk_area = np.full(disk_xy.shape[0], vehicle.propeller.disk_area_m2 / (disk_xy.shape[0] / 4))
    return np.concatenate([disk_xy, fr.position_m[:, :2]]), np.concatenate([disk_area, fr.area_m2])


@lru_cache(maxsize=64)
def _footprint_extent(vehicle: Vehicle, disc: Discretisation) -> tuple[float, float]:
    """(rho, A): the largest horizontal distance of a footprint point from the centre, m, and the
    footprint's total area, m^2 (for :func:`_flux_bound`)."""
    pts, area = _footprint(vehicle, disc)
    return float(np.sqrt(np.max(np.sum(pts**2, axis=1)))), float(area.sum())


_CHUNK = 8192  # rows per block of the (rows, K) flux sum (bounds temporary memory)
EXACT_ONE_SHARE = 2.0**-60
"""eta * phi below this leaves the factor 1 - eta phi exactly 1.0 in double precision (1 - x
rounds to 1 for x < 2^-54; the margin 2^-6 covers the rounding of the bound itself), -."""


def intercepted_flux_fraction(
    upper: Vehicle, middle: Vehicle, offsets_m: np.ndarray, disc: Discretisation = DEFAULT_DISCRETISATION
) -> np.ndarray:
    """phi (N,), -: share of ``upper``'s jet momentum flux at ``middle``'s rotor plane that passes
    through ``middle``'s four rotor disks or hits its frame (module docstring), for offsets (N, 3) = p_middle - p_upper,
    world frame, m. Zero where ``middle`` is not below ``upper``."""
    off = np.atleast_2d(np.asarray(offsets_m, dtype=float))
    dz = -off[:, 2]
    out = np.zeros(off.shape[0])
    rows = np.flatnonzero(dz > _MIN_DZ_M)
    if rows.size == 0:
        return out
    c_rad = upper.downwash.c_rad
    pts, area = _footprint(middle, disc)  # (K, 2), (K,)
    for lo in range(0, rows.size, _CHUNK):
        sel = rows[lo : lo + _CHUNK]
        a = axial_distance_m(upper, dz[sel])  # (M,), m
        xy = off[sel, None, :2] + pts[None, :, :]  # (M, K, 2) footprint points relative to the jet axis
        r_sq = np.sum(xy**2, axis=2)
        flux = np.exp(-2.0 * c_rad * r_sq / (a * a)[:, None]) @ area  # (M,) integral of (V/V_max)^2, m^2
        phi = 2.0 * c_rad / (math.pi * a * a) * flux
        out[sel] = np.clip(phi, 0.0, 1.0)
    return out


def _flux_bound(c_rad: float, rho_m, area_m2, r_m, a_m) -> np.ndarray:
    """An upper bound of phi (any shape, -) of a jet of radial constant ``c_rad`` on a footprint of
    extent ``rho_m`` (m) and area ``area_m2`` (m^2) at horizontal centre distance ``r_m`` and
    axial distance ``a_m`` (m): every footprint point is at least r - rho from the jet axis, so each
    term of phi is at most exp(-2 c_rad (r - rho)^2 / a^2) and phi <= 2 c_rad A / (pi a^2) that."""
    gap = np.maximum(np.asarray(r_m) - rho_m, 0.0)
    return 2.0 * c_rad * area_m2 / (math.pi * a_m * a_m) * np.exp(-2.0 * c_rad * gap * gap / (a_m * a_m))


def shielding_reach_m(
    upper: Vehicle, middle: Vehicle, eta: float, dz_max_m: float, disc: Discretisation = DEFAULT_DISCRETISATION
) -> float:
    """Horizontal centre distance, m, beyond which ``middle`` leaves ``upper``'s factor exactly 1.0
    (eta phi < :data:`EXACT_ONE_SHARE`) wherever it is at most ``dz_max_m`` (m) below ``upper``:
    the bound of :func:`_flux_bound` maximised over the axial distances a in [a(0), a(dz_max)]
    (it grows with a up to a^2 = 2 c_rad (r - rho)^2, then falls)."""
    if eta <= 0.0:
        return 0.0
    a_lo = float(axial_distance_m(upper, np.array(0.0)))
    a_hi = float(axial_distance_m(upper, np.array(max(dz_max_m, 0.0))))
    rho, area = _footprint_extent(middle, disc)
    c_rad = upper.downwash.c_rad

    def worst(r: float) -> float:
        a = min(max(math.sqrt(2.0 * c_rad) * max(r - rho, 0.0), a_lo), a_hi)
        return eta * float(_flux_bound(c_rad, rho, area, r, a))

    lo, hi = 0.0, rho + a_hi
    while worst(hi) >= EXACT_ONE_SHARE:
        lo, hi = hi, 2.0 * hi
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if worst(mid) >= EXACT_ONE_SHARE else (lo, mid)
    return hi


def pass_through_share(
    upper: Vehicle, middle: Vehicle, offsets_m: np.ndarray, eta: float, disc: Discretisation = DEFAULT_DISCRETISATION
) -> np.ndarray:
    """max(1 - eta phi, 0) (N,), -: the share of ``upper``'s jet that ``middle`` lets pass, for
    offsets (N, 3) = p_middle - p_upper, world frame, m (one factor of s_U, module docstring). 1
    where ``middle`` is not below ``upper``; exactly 1.0, without evaluating phi, where the bound
    of :func:`_flux_bound` says eta phi < :data:`EXACT_ONE_SHARE` (1 - eta phi would round to 1.0)."""
    off = np.atleast_2d(np.asarray(offsets_m, dtype=float))
    out = np.ones(off.shape[0])
    if eta <= 0.0:
        return out
    rho, area = _footprint_extent(middle, disc)
    dz = -off[:, 2]
    bound = _flux_bound(upper.downwash.c_rad, rho, area, np.hypot(off[:, 0], off[:, 1]), axial_distance_m(upper, dz))
    rows = np.flatnonzero((dz > _MIN_DZ_M) & (eta * bound >= EXACT_ONE_SHARE))
    if rows.size:
        out[rows] = np.maximum(1.0 - eta * intercepted_flux_fraction(upper, middle, off[rows], disc), 0.0)
    return out


def shielding_factors(
    target_offsets_m: Sequence[np.ndarray],
    sources: Sequence[Vehicle],
    eta: float,
    disc: Discretisation = DEFAULT_DISCRETISATION,
) -> list[np.ndarray]:
    """Per source j, s_j (N,), -: the share of its jet that reaches the target (module docstring).

    Args:
        target_offsets_m: per source, (N, 3) p_target - p_source, world frame, m.
        sources: the source vehicles, same order.
        eta: shielding efficiency in [0, MAX_STACK_SHIELDING], -.
    Returns:
        One (N,) array per source, each in [0, 1]; all ones when ``eta`` is 0 or fewer than two
        sources are above the target.

    Vectorised over the (source j, source k between, sample) triples: each pair of vehicles is one
    call of :func:`pass_through_share` over all its triples, and the factors of each s_j multiply
    in the order of k, as one loop over k would.
    """
    n_src = len(sources)
    offs = [np.atleast_2d(np.asarray(o, dtype=float)) for o in target_offsets_m]
    n = offs[0].shape[0] if offs else 0
    factors = np.ones((n_src, n))
    if eta <= 0.0 or n_src < 2:
        return list(factors)
    stacked = np.stack(offs)  # (S, N, 3)
    above = -stacked[:, :, 2] > _MIN_DZ_M  # (S, N) source above the target
    live = np.flatnonzero(above.any(axis=1))
    parts: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []
    for j in live:
        # triples (j, k, row): k between j and the target (p_k - p_j = o_j - o_k below j), both above
        ks = live[live != j]
        mid = stacked[j][None, :, :] - stacked[ks]  # (K, N, 3) p_k - p_j
        kk, rows = np.nonzero(above[j][None, :] & above[ks] & (-mid[:, :, 2] > _MIN_DZ_M))
        if kk.size:
            parts.append((np.full(kk.size, j), ks[kk], rows, mid[kk, rows]))
    if not parts:
        return list(factors)
    js, ks_all, rows, mids = (np.concatenate(x) for x in zip(*parts))
    kinds = list(dict.fromkeys(sources))  # the distinct vehicles
    kind = np.array([kinds.index(v) for v in sources])
    pair = kind[js] * len(kinds) + kind[ks_all]
    values = np.empty(js.size)
    for p in np.unique(pair):  # one call per (upper, middle) vehicle pair
        sel = pair == p
        values[sel] = pass_through_share(kinds[p // len(kinds)], kinds[p % len(kinds)], mids[sel], eta, disc)
    flat = js * n + rows
    order = np.lexsort((ks_all, flat))  # per (j, row), in the order of k
    np.multiply.at(factors.reshape(-1), flat[order], values[order])
    return list(factors)
