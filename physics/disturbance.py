"""Disturbance wrench on a target vehicle in the downwash of a hovering source (S0 section II).

Frames: world z up; both vehicles hover level with their body axes aligned to the world axes, so
body and world vectors coincide. ``offsets_m`` are ``p_target - p_source`` (N, 3), m; vertical
separation dz = -offset_z (positive when the target is below).

Two mechanisms are summed:

* frame drag (S0-3, S0-4): each frame area element feels 1/2 C_D rho V^2 dA along -z, C_D = 1.18;
  its torque is (r' - r) x F about the target's centre of mass;
* propeller thrust change (S0-5..S0-8): Delta f_i = -b_v v_on,i omega_i^2 with omega_i^2 = f_hover / k1
  and v_on,i the oncoming speed averaged over rotor i's disk; torque (r_i - r) x z_B Delta f_i.

Each offset carries a validity flag: the field model holds in the zone of established flow,
dz > 3 L of the source (S0 II-A).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from proxplan.physics.geometry import Discretisation, disk_samples, frame_elements
from proxplan.physics.propeller import AIR_DENSITY_KGPM3
from proxplan.physics.stack import MAX_STACK_SHIELDING
from proxplan.physics.vehicles import Vehicle
from proxplan.physics.velocity_field import (
    DEFAULT_FIELD_FORM,
    FIELD_FORMS,
    axial_distance_m,
    centreline_speed_mps,
    radial_profile,
)

FLAT_PLATE_DRAG_COEFFICIENT = 1.18
"""C_D of a flat plate normal to the flow (S0 II-B, McCormick), -."""

VALIDITY_FACTOR_L = 3.0
"""The field is valid for dz > VALIDITY_FACTOR_L * L of the source (S0 II-A), -."""

_CHUNK = 8192  # offsets per vectorised block (bounds temporary memory to a few tens of MB)
PROFILE_CUTOFF = 50.0
"""Rows where the Gaussian exponent c_rad (r / (dz - z0))^2 of (S0-2) exceeds this at EVERY sample point of
the target (or the target is not below the source: V_max = 0) are not evaluated: their wrench is below
exp(-50) = 2e-22 of the jet's (zero to double precision), and most rows of a flight log or a map lie there, -."""


@dataclass(frozen=True)
class ModelOptions:
    """Options of the disturbance model; the defaults are the product's standard model."""

    field_form: str = DEFAULT_FIELD_FORM  # "inverse-z" or "printed" form of (S0-1)
    drag_coefficient: float = FLAT_PLATE_DRAG_COEFFICIENT  # C_D, -
    air_density_kgpm3: float = AIR_DENSITY_KGPM3  # rho, kg/m^3
    discretisation: Discretisation = Discretisation()
    stack_shielding: float = 1.0  # eta of proxplan.physics.stack: share of an upper jet's flux a lower source's
    # disks take out of it before it reaches the target (0: S0's per-pair sum), -

    def __post_init__(self) -> None:
        if self.field_form not in FIELD_FORMS:
            raise ValueError(f"field_form must be one of {FIELD_FORMS}, got {self.field_form!r}")
        if not 0.0 <= self.stack_shielding <= MAX_STACK_SHIELDING:
            raise ValueError(f"stack_shielding must lie in [0, {MAX_STACK_SHIELDING:g}], got {self.stack_shielding!r}")


DEFAULT_OPTIONS = ModelOptions()


@dataclass(frozen=True)
class WrenchBatch:
    """Disturbance wrenches on the target for N offsets; forces in N, torques in N m, world frame."""

    offsets_m: np.ndarray  # (N, 3) target minus source position, m
    drag_force_N: np.ndarray  # (N, 3)
    drag_torque_Nm: np.ndarray  # (N, 3) about the target's centre of mass
    thrust_force_N: np.ndarray  # (N, 3) from propeller thrust change
    thrust_torque_Nm: np.ndarray  # (N, 3)
    valid: np.ndarray  # (N,) bool: dz > 3 L of the source (zone of established flow)

    @property
    def force_N(self) -> np.ndarray:
        """Total force (N, 3), N."""
        return self.drag_force_N + self.thrust_force_N

    @property
    def torque_Nm(self) -> np.ndarray:
        """Total torque (N, 3) about the target's centre of mass, N m."""
        return self.drag_torque_Nm + self.thrust_torque_Nm


def validity_mask(source: Vehicle, offsets_m: np.ndarray) -> np.ndarray:
    """True where the target is in the source's zone of established flow, dz > 3 L, shape (N,)."""
    return -np.asarray(offsets_m)[:, 2] > VALIDITY_FACTOR_L * source.size_m


def invalid_zone_mask(source: Vehicle, target: Vehicle, offsets_m: np.ndarray, tube_m=0.0) -> np.ndarray:
    """True where the target is in the source's invalid zone, shape (N,): below it within
    dz <= 3 L (S0 II-A) with overlapping footprints (horizontal distance < the sum of the body
    radii), both grown by the tracking tube ``tube_m`` (m, scalar or (N,)). The one definition
    the verifier, the planner's metrics and the simulator's reports share."""
    off = np.asarray(offsets_m, dtype=float)
    dz = -off[:, 2]
    r = np.hypot(off[:, 0], off[:, 1])
    return (
        (dz > 1e-6)
        & (dz <= VALIDITY_FACTOR_L * source.size_m + tube_m)
        & (r < source.body_radius_m + target.body_radius_m + tube_m)
    )


def vertical_point_wrench(points_m: np.ndarray, force_z_N: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sum vertical point forces (N, K), N, at body points (K, 3), m, into force (N, 3), N, and
    torque about the centre of mass (N, 3), N m: tau = r x (0, 0, F_z) (S0-4, S0-8)."""
    n = force_z_N.shape[0]
    force = np.zeros((n, 3))
    force[:, 2] = force_z_N.sum(axis=1)
    torque = np.zeros((n, 3))
    torque[:, 0] = force_z_N @ points_m[:, 1]  # tau_x = y F_z
    torque[:, 1] = -(force_z_N @ points_m[:, 0])  # tau_y = -x F_z
    return force, torque


def _planar_profile(
    source: Vehicle,
    offsets_m: np.ndarray,
    points_m: np.ndarray,
    options: ModelOptions,
) -> tuple[np.ndarray, np.ndarray]:
    """Factored (S0-2) at body points that share one height (the rotor plane, geometry module).

    Returns V_max (N,), m/s, and radial_profile((r / (dz - z0))^2) (N, K), -, for offsets (N, 3)
    and points (K, 3); V at a point is V_max * profile. r^2 is expanded as |o|^2 + 2 o.p + |p|^2, computed in place, so the (N, K) work is
    one matrix product and one exponential.
    """
    dz_m = -(offsets_m[:, 2] + points_m[0, 2])  # all points share the rotor plane (geometry)
    v_max = centreline_speed_mps(source, dz_m, form=options.field_form, air_density_kgpm3=options.air_density_kgpm3)
    inv_axial_sq = 1.0 / axial_distance_m(source, dz_m) ** 2
    off_xy, pts_xy = offsets_m[:, :2], points_m[:, :2]
    scaled = off_xy @ (2.0 * pts_xy.T)  # 2 o.p, (N, K)
    scaled += (off_xy**2).sum(axis=1)[:, None]
    scaled += (pts_xy**2).sum(axis=1)[None, :]
    np.maximum(scaled, 0.0, out=scaled)  # r^2 >= 0 despite rounding
    scaled *= inv_axial_sq[:, None]
    return v_max, radial_profile(source, scaled)


def _in_reach(source: Vehicle, offsets_m: np.ndarray, points_m: np.ndarray) -> np.ndarray:
    """(N,) bool: the rows where some of the target's ``points_m`` (K, 3) can see the jet (module constant
    :data:`PROFILE_CUTOFF`): below the source, and the nearest point's Gaussian exponent under the cut-off."""
    dz_m = -(offsets_m[:, 2] + points_m[0, 2])
    reach = float(np.max(np.hypot(points_m[:, 0], points_m[:, 1]))) if len(points_m) else 0.0
    gap = np.maximum(np.hypot(offsets_m[:, 0], offsets_m[:, 1]) - reach, 0.0)
    return (dz_m > 0.0) & (source.downwash.c_rad * gap**2 / axial_distance_m(source, dz_m) ** 2 < PROFILE_CUTOFF)


def _disk_average_speed(source: Vehicle, target: Vehicle, offsets_m: np.ndarray, options: ModelOptions) -> np.ndarray:
    """(N, 4) disk-averaged oncoming speed, m/s (equal-weight quadrature of the geometry module)."""
    disks = disk_samples(target, options.discretisation)
    out = np.zeros((offsets_m.shape[0], 4))
    rows = _in_reach(source, offsets_m, disks.flat_position_m)
    if rows.any():
        v_max, profile = _planar_profile(source, offsets_m[rows], disks.flat_position_m, options)
        out[rows] = v_max[:, None] * (profile @ disks.averaging)
    return out


def oncoming_speed_per_rotor_mps(
    source: Vehicle,
    target: Vehicle,
    offsets_m: np.ndarray,
    options: ModelOptions = DEFAULT_OPTIONS,
) -> np.ndarray:
    """Oncoming downwash speed averaged over each target rotor disk (N, 4), m/s, (S0-6) v_on,i.

    Rotor order (S0-14); offsets (N, 3) = p_target - p_source, world frame, m.
    """
    offsets = _checked_offsets(offsets_m)
    parts = [
        _disk_average_speed(source, target, offsets[i : i + _CHUNK], options)
        for i in range(0, offsets.shape[0], _CHUNK)
    ]
    return np.concatenate(parts) if parts else np.zeros((0, 4))


def _checked_offsets(offsets_m: np.ndarray) -> np.ndarray:
    offsets = np.atleast_2d(np.asarray(offsets_m, dtype=float))
    if offsets.ndim != 2 or offsets.shape[1] != 3:
        raise ValueError(f"offsets_m must have shape (N, 3), got {np.shape(offsets_m)}")
    if not np.all(np.isfinite(offsets)):
        raise ValueError("offsets_m must be finite")
    return offsets


@dataclass(frozen=True)
class _TargetSamples:
    """All sample points of a target in one array: frame elements first, then disk points."""

    points_m: np.ndarray  # (E + 4 P, 3) body frame, m
    n_frame: int  # E
    frame_points_m: np.ndarray  # (E, 3)
    frame_area_m2: np.ndarray  # (E,)
    disk_averaging: np.ndarray  # (4 P, 4)


@lru_cache(maxsize=64)
def _target_samples(target: Vehicle, disc: Discretisation) -> _TargetSamples:
    frame = frame_elements(target, disc)
    disks = disk_samples(target, disc)
    points = np.concatenate([frame.position_m, disks.flat_position_m])
    return _TargetSamples(points, len(frame.area_m2), frame.position_m, frame.area_m2, disks.averaging)


def _wrench_block(
    source: Vehicle, target: Vehicle, offsets_m: np.ndarray, options: ModelOptions
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Drag force, drag torque, thrust-change force and torque, each (N, 3), of one block of offsets; the rows
    out of the jet's reach (:func:`_in_reach`) are zero without being evaluated."""
    samples = _target_samples(target, options.discretisation)
    rows = _in_reach(source, offsets_m, samples.points_m)
    if rows.all():
        return _wrench_rows(source, target, offsets_m, options, samples)
    out = tuple(np.zeros((offsets_m.shape[0], 3)) for _ in range(4))
    if rows.any():
        for full, part in zip(out, _wrench_rows(source, target, offsets_m[rows], options, samples)):
            full[rows] = part
    return out  # type: ignore[return-value]


def _wrench_rows(
    source: Vehicle, target: Vehicle, offsets_m: np.ndarray, options: ModelOptions, samples: _TargetSamples
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    v_max, profile = _planar_profile(source, offsets_m, samples.points_m, options)
    # (S0-3): dF_z = -1/2 C_D rho V^2 dA with V^2 = V_max^2 profile^2; (S0-4) torque about the CoM
    drag_z = profile[:, : samples.n_frame] ** 2
    drag_z *= samples.frame_area_m2
    drag_z *= ((-0.5 * options.drag_coefficient * options.air_density_kgpm3) * v_max**2)[:, None]
    drag_f, drag_t = vertical_point_wrench(samples.frame_points_m, drag_z)

    # disk-averaged oncoming speed v_on,i (N, 4)
    v_on = v_max[:, None] * (profile[:, samples.n_frame :] @ samples.disk_averaging)
    # (S0-6): Delta f_i = -b_v v_on,i omega_i^2, omega_i^2 = f_hover / k1 ; (S0-7, S0-8) sums
    delta_f = (-target.b_v * target.hover_omega_sq_rad2ps2) * v_on
    thrust_f, thrust_t = vertical_point_wrench(target.rotor_positions_m, delta_f)
    return drag_f, drag_t, thrust_f, thrust_t


def disturbance_wrench(
    source: Vehicle,
    target: Vehicle,
    offsets_m: np.ndarray,
    options: ModelOptions = DEFAULT_OPTIONS,
) -> WrenchBatch:
    """Wrench on ``target`` from the downwash of ``source`` for each offset, vectorised.

    Args:
        source: hovering vehicle producing the downwash.
        target: vehicle receiving it (hovering, level, yaw aligned with the source).
        offsets_m: (N, 3) or (3,) positions of the target relative to the source, world frame, m.
        options: field form, C_D, air density and discretisation.

    Returns:
        A :class:`WrenchBatch` with (N, 3) arrays; a (3,) input gives N = 1.
    """
    offsets = _checked_offsets(offsets_m)
    blocks = [
        _wrench_block(source, target, offsets[i : i + _CHUNK], options) for i in range(0, offsets.shape[0], _CHUNK)
    ]
    if blocks:
        drag_f, drag_t, thrust_f, thrust_t = (np.concatenate(parts) for parts in zip(*blocks))
    else:
        drag_f = drag_t = thrust_f = thrust_t = np.zeros((0, 3))
    return WrenchBatch(
        offsets_m=offsets,
        drag_force_N=drag_f,
        drag_torque_Nm=drag_t,
        thrust_force_N=thrust_f,
        thrust_torque_Nm=thrust_t,
        valid=validity_mask(source, offsets),
    )
