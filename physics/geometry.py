"""Sample points on a target vehicle: frame area elements and propeller-disk quadrature.

Body frame x forward, y left, z up, origin at the centre of mass; all points lie in the rotor plane
(z = 0), which the disturbance module relies on. These discretisations feed the drag integral (S0-3, S0-4) and the disk-averaged oncoming
flow of the thrust change (S0-6..S0-8).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from proxplan.physics.vehicles import MOTOR_DIRECTIONS_XY, Vehicle


@dataclass(frozen=True)
class Discretisation:
    """How finely the target is sampled; the defaults are the product's standard resolution."""

    disk_rings: int = 4  # equal-area rings per propeller disk
    disk_spokes: int = 8  # points per ring
    hub_cells: int = 3  # hub split into hub_cells x hub_cells squares
    arm_segments: int = 4  # segments per arm


@dataclass(frozen=True)
class FrameElements:
    """Frame area elements: centres ``position_m`` (E, 3) body frame, m; ``area_m2`` (E,), m^2."""

    position_m: np.ndarray
    area_m2: np.ndarray
    part: tuple[str, ...]  # "hub", "arm" or "motor_pod" per element


@dataclass(frozen=True)
class DiskSamples:
    """Quadrature over each propeller disk, equal weights.

    ``position_m`` (4, P, 3) body frame, m; ``flat_position_m`` the same as (4 P, 3);
    ``averaging`` (4 P, 4) maps values at the points to per-disk means (values @ averaging).
    """

    position_m: np.ndarray
    flat_position_m: np.ndarray
    averaging: np.ndarray


@lru_cache(maxsize=64)
def frame_elements(vehicle: Vehicle, disc: Discretisation = Discretisation()) -> FrameElements:
    """Split the projected frame (hub, four arms, four motor pods) into area elements."""
    f = vehicle.frame
    positions: list[np.ndarray] = []
    areas: list[float] = []
    parts: list[str] = []
    cell_m = f.hub_side_m / disc.hub_cells
    centres = (np.arange(disc.hub_cells) + 0.5) * cell_m - 0.5 * f.hub_side_m
    for cx in centres:
        for cy in centres:
            positions.append(np.array([cx, cy, 0.0]))
            areas.append(cell_m * cell_m)
            parts.append("hub")
    arm_start_m = 0.5 * f.hub_side_m
    arm_end_m = max(vehicle.arm_length_m - 0.5 * f.motor_pod_diameter_m, arm_start_m)
    seg_len_m = (arm_end_m - arm_start_m) / disc.arm_segments
    unit = MOTOR_DIRECTIONS_XY / math.sqrt(2.0)
    for direction in unit:
        for k in range(disc.arm_segments):
            radial_m = arm_start_m + (k + 0.5) * seg_len_m
            positions.append(np.array([*(direction * radial_m), 0.0]))
            areas.append(f.arm_width_m * seg_len_m)
            parts.append("arm")
    for rotor in vehicle.rotor_positions_m:
        positions.append(rotor.copy())
        areas.append(math.pi * (0.5 * f.motor_pod_diameter_m) ** 2)
        parts.append("motor_pod")
    pos = np.array(positions)
    pos.setflags(write=False)
    area = np.array(areas)
    area.setflags(write=False)
    return FrameElements(position_m=pos, area_m2=area, part=tuple(parts))


@lru_cache(maxsize=64)
def disk_samples(vehicle: Vehicle, disc: Discretisation = Discretisation()) -> DiskSamples:
    """Equal-area polar quadrature points on each rotor disk (midpoint rule in r^2 and angle)."""
    radius_m = vehicle.propeller.radius_m
    ring_r = radius_m * np.sqrt((np.arange(disc.disk_rings) + 0.5) / disc.disk_rings)
    points = []
    for i, r in enumerate(ring_r):
        phase = 0.5 * (i % 2)  # stagger alternate rings
        angles = 2.0 * math.pi * (np.arange(disc.disk_spokes) + phase) / disc.disk_spokes
        points.append(np.column_stack([r * np.cos(angles), r * np.sin(angles)]))
    disk_xy = np.concatenate(points)  # (P, 2)
    rotors = vehicle.rotor_positions_m  # (4, 3)
    pos = np.zeros((4, disk_xy.shape[0], 3))
    pos[:, :, :2] = rotors[:, None, :2] + disk_xy[None, :, :]
    pos.setflags(write=False)
    n_rotor, n_pts = pos.shape[:2]
    averaging = np.kron(np.eye(n_rotor), np.full((n_pts, 1), 1.0 / n_pts))
    averaging.setflags(write=False)
    return DiskSamples(position_m=pos, flat_position_m=pos.reshape(-1, 3), averaging=averaging)
