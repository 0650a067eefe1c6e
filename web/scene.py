"""Scene content of the review app: ground, workspace, obstacles, vehicle models, trajectories.

World frame z up, m. Node names (stable, tests and users rely on them):
``/ground``, ``/workspace``, ``/obstacles/<k>``, ``/vehicles/<name>`` (with children ``body``,
``props`` and ``label``), ``/trajectories/<name>``. Trajectory colours show the vehicle's authority
usage (DESIGN.md section 3) relative to the scenario's ``limits.authority_fraction``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

import proxplan.web.meshes as meshes
from proxplan.physics import Vehicle
from proxplan.web.review_data import ReviewData

VEHICLE_COLOURS = [
    (31, 119, 180),
    (255, 127, 14),
    (44, 160, 44),
    (148, 103, 189),
    (140, 86, 75),
    (227, 119, 194),
    (23, 190, 207),
    (188, 189, 34),
]
OVER_LIMIT_RGB = (200, 0, 200)  # trajectory colour where usage exceeds the limit
USAGE_COLORMAP = "RdYlGn_r"


def vehicle_meshes(vehicle: Vehicle) -> tuple[meshes.Mesh, meshes.Mesh]:
    """(body, propeller disks) meshes of ``vehicle`` in its body frame (x forward, z up), m.

    Built from its own geometry: square hub, four arms to the rotor axes (S0-14 positions), motor
    pods, and one disk of the propeller radius above each pod.
    """
    f = vehicle.frame
    hub_h = max(0.4 * f.hub_side_m, 0.01)
    parts = [meshes.box(np.zeros(3), np.array([f.hub_side_m, f.hub_side_m, hub_h]))]
    arm_h = max(0.5 * f.arm_width_m, 0.004)
    for rotor in vehicle.rotor_positions_m:
        yaw = math.atan2(rotor[1], rotor[0])
        parts.append(meshes.box(0.5 * rotor, np.array([vehicle.arm_length_m, f.arm_width_m, arm_h]), yaw_rad=yaw))
        parts.append(meshes.cylinder(rotor, 0.5 * f.motor_pod_diameter_m, hub_h))
    body = meshes.merge(parts)
    disk_h = max(0.02 * vehicle.propeller.radius_m, 0.001)
    disks = meshes.merge(
        [
            meshes.cylinder(rotor + [0.0, 0.0, 0.5 * hub_h + disk_h], vehicle.propeller.radius_m, disk_h)
            for rotor in vehicle.rotor_positions_m
        ]
    )
    return body, disks


def usage_colours(usage: np.ndarray, limit: float) -> np.ndarray:
    """RGB (N, 3) uint8 for authority usage (N,): green 0 .. red at ``limit``, magenta above."""
    from matplotlib import colormaps

    frac = np.clip(np.asarray(usage, float) / max(limit, 1e-9), 0.0, 1.0)
    rgb = (colormaps[USAGE_COLORMAP](frac)[:, :3] * 255).astype(np.uint8)
    rgb[np.asarray(usage) > limit] = OVER_LIMIT_RGB
    return rgb


def trajectory_segments(position_m: np.ndarray, usage: np.ndarray, limit: float) -> tuple[np.ndarray, np.ndarray]:
    """Line segments (N-1, 2, 3), m, between samples and their colours (N-1, 2, 3) uint8."""
    pts = np.asarray(position_m, float)
    if pts.shape[0] < 2:
        pts = np.vstack([pts, pts])
        usage = np.concatenate([usage, usage])
    segs = np.stack([pts[:-1], pts[1:]], axis=1)
    rgb = usage_colours(usage, limit)
    cols = np.stack([rgb[:-1], rgb[1:]], axis=1)
    return segs, cols


@dataclass
class SceneHandles:
    """Handles of the plan-dependent nodes, so they can be moved, toggled or replaced."""

    vehicles: dict[str, Any] = field(default_factory=dict)  # /vehicles/<name> frames
    trajectories: dict[str, Any] = field(default_factory=dict)
    obstacles: list[Any] = field(default_factory=list)
    models: dict[str, list[Any]] = field(default_factory=dict)  # body and props meshes per vehicle
    fixed: list[Any] = field(default_factory=list)  # ground, workspace

    def remove(self) -> None:
        for handle in [*self.vehicles.values(), *self.trajectories.values(), *self.obstacles, *self.fixed]:
            handle.remove()
        self.vehicles.clear()
        self.trajectories.clear()
        self.obstacles.clear()
        self.models.clear()
        self.fixed.clear()


def build_scene(
    scene: Any,
    data: ReviewData,
    *,
    usage: dict[str, np.ndarray] | None = None,
    model_scale: float = 1.0,
) -> SceneHandles:
    """Add every plan node to ``scene`` (a viser SceneApi).

    ``usage`` maps vehicle names to authority usage (N,) on that vehicle's ``t_s``; missing
    vehicles are drawn grey. ``model_scale`` enlarges the vehicle models (not the trajectories).
    """
    handles = SceneHandles()
    lo, hi = data.workspace_min_m, data.workspace_max_m
    size = hi - lo
    centre = 0.5 * (lo + hi)
    handles.fixed.append(
        scene.add_grid(
            "/ground",
            width=float(size[0]),
            height=float(size[1]),
            plane="xy",
            cell_size=0.5,
            section_size=1.0,
            position=(float(centre[0]), float(centre[1]), 0.0),
        )
    )
    handles.fixed.append(
        scene.add_line_segments(
            "/workspace", meshes.box_edges(lo, hi), (120, 120, 120), thickness=2.0, thickness_units="screen"
        )
    )
    for k, (bmin, bmax) in enumerate(data.obstacles_m):
        handles.obstacles.append(
            scene.add_box(
                f"/obstacles/{k}",
                color=(150, 150, 160),
                dimensions=tuple(bmax - bmin),
                position=tuple(0.5 * (bmin + bmax)),
                opacity=0.7,
            )
        )
    for i, (name, traj) in enumerate(data.vehicles.items()):
        colour = VEHICLE_COLOURS[i % len(VEHICLE_COLOURS)]
        u = usage.get(name) if usage else None
        if u is None:
            segs, cols = trajectory_segments(traj.position_m, np.zeros(len(traj.t_s)), 1.0)
            cols[:] = 160
        else:
            segs, cols = trajectory_segments(traj.position_m, u, data.authority_fraction)
        handles.trajectories[name] = scene.add_line_segments(
            f"/trajectories/{name}", segs, cols, thickness=4.0, thickness_units="screen"
        )
        frame = scene.add_frame(f"/vehicles/{name}", show_axes=False, position=tuple(traj.position_m[0]))
        body, disks = vehicle_meshes(traj.vehicle)
        handles.models[name] = [
            scene.add_mesh_simple(f"/vehicles/{name}/body", body[0], body[1], color=(60, 60, 60), scale=model_scale),
            scene.add_mesh_simple(
                f"/vehicles/{name}/props",
                disks[0],
                disks[1],
                color=colour,
                opacity=0.6,
                scale=model_scale,
                side="double",
            ),
        ]
        scene.add_label(
            f"/vehicles/{name}/label", name, position=(0.0, 0.0, 0.1 + model_scale * traj.vehicle.arm_length_m)
        )
        handles.vehicles[name] = frame
    return handles


def set_time(handles: SceneHandles, data: ReviewData, t_s: float) -> dict[str, np.ndarray]:
    """Move every vehicle model to its planned position at ``t_s``; returns the positions (3,), m."""
    positions = data.positions_at(t_s)
    for name, pos in positions.items():
        frame = handles.vehicles.get(name)
        if frame is not None:
            frame.position = pos
    return positions


def set_model_scale(handles: SceneHandles, scale: float) -> None:
    """Resize every vehicle model (body and propeller disks) by ``scale``, -."""
    for parts in handles.models.values():
        for handle in parts:
            handle.scale = scale


def readable_model_scale(data: ReviewData, *, fraction: float = 0.1, max_scale: float = 20.0) -> float:
    """Model scale (multiple of 0.5, 1 .. ``max_scale``) at which the largest vehicle spans about
    ``fraction`` of the workspace diagonal, -."""
    diag_m = float(np.linalg.norm(data.workspace_max_m - data.workspace_min_m))
    size_m = max(v.vehicle.size_m + 2 * v.vehicle.propeller.radius_m for v in data.vehicles.values())
    return float(np.clip(np.floor(2.0 * fraction * diag_m / size_m) / 2.0, 1.0, max_scale))
