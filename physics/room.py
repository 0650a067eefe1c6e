"""Planes of the room a flight happens in (floor, walls, ceiling), for features of a vehicle's place.

A manifest (``planes:``) declares them; :mod:`proxplan.physics.features` turns the distance of a
vehicle's centre to each plane into kernels, so discovery can find an effect tied to a place in the
room (a wall's recirculation, a ceiling) without naming it. World frame, z up, metres.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from proxplan.fileio import UserError

MAX_PLANES = 8
"""At most this many planes per manifest, -."""


@dataclass(frozen=True)
class Plane:
    """An infinite plane through ``point_m`` (3,) m with unit ``normal`` (3,) pointing into the room."""

    name: str
    point_m: tuple[float, float, float]
    normal: tuple[float, float, float]

    def distance_m(self, position_m: np.ndarray) -> np.ndarray:
        """Signed distance (N,), m, of positions (N, 3), positive on the room side."""
        return (np.asarray(position_m, dtype=float) - np.asarray(self.point_m)) @ np.asarray(self.normal)


def planes_from_list(raw: Any, where: str) -> tuple[Plane, ...]:
    """Planes from a YAML list ``[{name, point_m: [x, y, z], normal: [nx, ny, nz]}]``; UserError
    naming ``where`` on a malformed entry. The normal is normalised."""
    if raw is None:
        return ()
    if not isinstance(raw, list) or len(raw) > MAX_PLANES:
        raise UserError(f"{where}: expected a list of at most {MAX_PLANES} {{name, point_m, normal}} planes")
    out = []
    for i, p in enumerate(raw):
        w = f"{where}[{i}]"
        try:
            point = np.asarray(p["point_m"], dtype=float).reshape(3)
            normal = np.asarray(p["normal"], dtype=float).reshape(3)
            name = str(p.get("name", f"plane{i}"))
        except (KeyError, TypeError, ValueError, AttributeError):
            raise UserError(f"{w}: expected {{name, point_m: [x, y, z] (m), normal: [nx, ny, nz]}}") from None
        norm = float(np.linalg.norm(normal))
        if not np.all(np.isfinite(point)) or not np.isfinite(norm) or norm < 1e-9:
            raise UserError(f"{w}: point_m must be finite and normal a non-zero vector")
        px, py, pz = (float(v) for v in point)
        nx, ny, nz = (float(v) / norm for v in normal)
        out.append(Plane(name, (px, py, pz), (nx, ny, nz)))
    return tuple(out)


def plane_distances_m(planes: Sequence[Plane], position_m: np.ndarray) -> np.ndarray:
    """(N, P) distances of positions (N, 3) to each plane, m (clipped at 0: behind a plane = on it)."""
    if not planes:
        return np.zeros((len(position_m), 0))
    return np.maximum(np.column_stack([p.distance_m(position_m) for p in planes]), 0.0)
