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


def intercepted_flux_fraction(
    upper: Vehicle, middle: Vehicle, offsets_m: np.ndarray, disc: Discretisation = DEFAULT_DISCRETISATION
) -> np.ndarray:
    """phi (N,), -: share of ``upper``'s jet momentum flux at ``middle``'s rotor plane that passes
    through ``middle``'s four rotor disks or hits its frame (module docstring), for offsets (N, 3) = p_middle - p_upper,
    world frame, m. Zero where ``middle`` is not below ``upper``."""
    off = np.atleast_2d(np.asarray(offsets_m, dtype=float))
    dz = -off[:, 2]
    out = np.zeros(off.shape[0])
    below = dz > _MIN_DZ_M
    if not below.any():
        return out
    c_rad = upper.downwash.c_rad
    a = axial_distance_m(upper, dz[below])  # (M,), m
    pts, area = _footprint(middle, disc)  # (K, 2), (K,)
    xy = off[below, None, :2] + pts[None, :, :]  # (M, K, 2) footprint points relative to the jet axis
    r_sq = np.sum(xy**2, axis=2)
    flux = np.exp(-2.0 * c_rad * r_sq / (a * a)[:, None]) @ area  # (M,) integral of (V/V_max)^2, m^2
    phi = 2.0 * c_rad / (math.pi * a * a) * flux
    out[below] = np.clip(phi, 0.0, 1.0)
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
    """
    n_src = len(sources)
    offs = [np.atleast_2d(np.asarray(o, dtype=float)) for o in target_offsets_m]
    n = offs[0].shape[0] if offs else 0
    factors = [np.ones(n) for _ in range(n_src)]
    if eta <= 0.0 or n_src < 2:
        return factors
    above = [(-o[:, 2]) > _MIN_DZ_M for o in offs]  # source above the target
    for j in range(n_src):
        for k in range(n_src):
            if k == j:
                continue
            # k between j and the target: above the target and below j (p_k - p_j = o_j - o_k)
            mid = offs[j] - offs[k]
            rows = above[j] & above[k] & (-mid[:, 2] > _MIN_DZ_M)
            if rows.any():
                phi = intercepted_flux_fraction(sources[j], sources[k], mid[rows], disc)
                factors[j][rows] *= np.maximum(1.0 - eta * phi, 0.0)
    return factors
