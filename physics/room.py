"""Planes of the room a flight happens in (floor, walls, ceiling), for features of a vehicle's place.

A manifest (``planes:``) declares them; :mod:`proxplan.physics.features` turns the distance of a
vehicle's centre to each plane into kernels, so discovery can find an effect tied to a place in the
room (a wall's recirculation, a ceiling) without naming it. World frame, z up, metres.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Annotated, Any

import numpy as np
from pydantic import Field, TypeAdapter, model_validator

from proxplan.fileio import FileModel, Text, Vec3, optional, problem, validate

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


class PlanePart(FileModel):
    """A plane of the room, as a manifest's ``planes:`` entry declares it."""

    name: Text = optional("name of the plane (default plane<i>)")
    point_m: Vec3 = Field(description="a point of the plane [x, y, z], world frame, m")
    normal: Vec3 = Field(description="normal [nx, ny, nz] pointing into the room (any non-zero length), -")

    @model_validator(mode="after")
    def _non_zero_normal(self) -> PlanePart:
        if float(np.linalg.norm(self.normal)) < 1e-9:
            raise problem(f"expected a non-zero vector, got {list(self.normal)}", at="normal")
        return self


PlaneList = Annotated[list[PlanePart], Field(max_length=MAX_PLANES)]
_PLANES: TypeAdapter[list[PlanePart] | None] = TypeAdapter(PlaneList | None)


def planes_from_parts(parts: Sequence[PlanePart] | None) -> tuple[Plane, ...]:
    """The planes of validated entries (normals normalised)."""
    out = []
    for i, p in enumerate(parts or ()):
        norm = float(np.linalg.norm(p.normal))
        nx, ny, nz = (float(v) / norm for v in p.normal)
        out.append(Plane(p.name if p.name is not None else f"plane{i}", p.point_m, (nx, ny, nz)))
    return tuple(out)


def planes_from_list(raw: Any, where: str) -> tuple[Plane, ...]:
    """Planes from a YAML list ``[{name, point_m: [x, y, z], normal: [nx, ny, nz]}]``; UserError
    naming ``where`` (``FILE: KEY``) on a malformed entry. The normal is normalised."""
    return planes_from_parts(validate(_PLANES, raw, label=where))


def plane_distances_m(planes: Sequence[Plane], position_m: np.ndarray) -> np.ndarray:
    """(N, P) distances of positions (N, 3) to each plane, m (clipped at 0: behind a plane = on it)."""
    if not planes:
        return np.zeros((len(position_m), 0))
    return np.maximum(np.column_stack([p.distance_m(position_m) for p in planes]), 0.0)
