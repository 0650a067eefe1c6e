"""Triangle-mesh primitives for the scene: boxes, cylinders, surfaces of revolution.

Every function returns ``(vertices (V, 3) float, faces (F, 3) int)`` in the caller's frame, m.
"""

from __future__ import annotations

import math

import numpy as np

Mesh = tuple[np.ndarray, np.ndarray]

_BOX_FACES = np.array(
    [
        [0, 2, 1],
        [0, 3, 2],
        [4, 5, 6],
        [4, 6, 7],
        [0, 1, 5],
        [0, 5, 4],
        [1, 2, 6],
        [1, 6, 5],
        [2, 3, 7],
        [2, 7, 6],
        [3, 0, 4],
        [3, 4, 7],
    ]
)


def box(centre_m: np.ndarray, size_m: np.ndarray, *, yaw_rad: float = 0.0) -> Mesh:
    """Box of edge lengths ``size_m`` (3,) centred at ``centre_m`` (3,), turned by ``yaw_rad`` about z."""
    sx, sy, sz = 0.5 * np.asarray(size_m, float)
    corners = np.array(
        [
            [-sx, -sy, -sz],
            [sx, -sy, -sz],
            [sx, sy, -sz],
            [-sx, sy, -sz],
            [-sx, -sy, sz],
            [sx, -sy, sz],
            [sx, sy, sz],
            [-sx, sy, sz],
        ]
    )
    c, s = math.cos(yaw_rad), math.sin(yaw_rad)
    rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return corners @ rot.T + np.asarray(centre_m, float), _BOX_FACES.copy()


def cylinder(centre_m: np.ndarray, radius_m: float, height_m: float, *, segments: int = 24) -> Mesh:
    """Closed cylinder with a vertical axis, centred at ``centre_m`` (3,)."""
    ang = 2.0 * math.pi * np.arange(segments) / segments
    ring = np.column_stack([radius_m * np.cos(ang), radius_m * np.sin(ang), np.zeros(segments)])
    bottom = ring - [0.0, 0.0, 0.5 * height_m]
    top = ring + [0.0, 0.0, 0.5 * height_m]
    verts = np.vstack([bottom, top, [[0, 0, -0.5 * height_m], [0, 0, 0.5 * height_m]]])
    i = np.arange(segments)
    j = (i + 1) % segments
    nb, nt = 2 * segments, 2 * segments + 1
    faces = np.vstack(
        [
            np.column_stack([i, j, j + segments]),
            np.column_stack([i, j + segments, i + segments]),
            np.column_stack([np.full(segments, nb), j, i]),
            np.column_stack([np.full(segments, nt), i + segments, j + segments]),
        ]
    )
    return verts + np.asarray(centre_m, float), faces


def surface_of_revolution(z_m: np.ndarray, r_m: np.ndarray, *, segments: int = 36) -> Mesh:
    """Surface swept by the profile r(z) (both (K,)) about the vertical axis through the origin.

    Rings with r = 0 collapse to points, so a closed jet tip renders without holes.
    """
    z_m = np.asarray(z_m, float)
    r_m = np.asarray(r_m, float)
    ang = 2.0 * math.pi * np.arange(segments) / segments
    verts = np.stack(
        [
            r_m[:, None] * np.cos(ang)[None, :],
            r_m[:, None] * np.sin(ang)[None, :],
            np.broadcast_to(z_m[:, None], (z_m.size, segments)),
        ],
        axis=-1,
    ).reshape(-1, 3)
    k = np.arange(z_m.size - 1)[:, None]
    i = np.arange(segments)[None, :]
    j = (i + 1) % segments
    a, b = k * segments + i, k * segments + j
    c, d = a + segments, b + segments
    faces = np.concatenate([np.stack([a, b, d], -1).reshape(-1, 3), np.stack([a, d, c], -1).reshape(-1, 3)])
    return verts, faces


def merge(meshes: list[Mesh]) -> Mesh:
    """Concatenate meshes into one (faces re-indexed)."""
    verts, faces, offset = [], [], 0
    for v, f in meshes:
        verts.append(v)
        faces.append(f + offset)
        offset += v.shape[0]
    return np.vstack(verts), np.vstack(faces)


def box_edges(lo_m: np.ndarray, hi_m: np.ndarray) -> np.ndarray:
    """The 12 edges of an axis-aligned box as line segments (12, 2, 3), m."""
    lo, hi = np.asarray(lo_m, float), np.asarray(hi_m, float)
    corners = np.array([[x, y, z] for z in (lo[2], hi[2]) for y in (lo[1], hi[1]) for x in (lo[0], hi[0])])
    pairs = [(0, 1), (2, 3), (4, 5), (6, 7), (0, 2), (1, 3), (4, 6), (5, 7), (0, 4), (1, 5), (2, 6), (3, 7)]
    return np.array([[corners[a], corners[b]] for a, b in pairs])
