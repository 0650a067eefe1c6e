"""Downwash layers of a selected source vehicle: iso-speed jet surfaces and the cutoff surface.

Both are surfaces of revolution about the source's vertical axis, in the source's frame (world axes,
origin at the source's centre of mass, z up; the jet points down, so z = -dz).

* Iso-speed surfaces: where the downwash speed V(dz, r) of (S0-1, S0-2) equals a level, found on a
  grid from ``proxplan.physics.velocity_field.downwash_speed_mps`` (the model's own code; no inversion by hand).
* Cutoff surface r_cut(dz): beyond it a target's authority usage stays below the limit, from the
  pair's cutoff map (``proxplan.costmaps.map_store.pair_maps``, with its invalid-zone rule for dz <= 3 L).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import proxplan.web.meshes as meshes
from proxplan.physics import Vehicle


@dataclass(frozen=True)
class Profile:
    """A surface-of-revolution profile: radius ``r_m`` (K,) at depth ``dz_m`` (K,) below the source, m."""

    dz_m: np.ndarray
    r_m: np.ndarray
    label: str

    def mesh(self, *, segments: int = 36) -> meshes.Mesh:
        """Triangle mesh of the surface in the source frame (z = -dz), m."""
        return meshes.surface_of_revolution(-self.dz_m, self.r_m, segments=segments)


DEFAULT_ISO_LEVELS_MPS = (4.0, 2.0, 1.0)
"""Downwash speeds drawn as iso-surfaces, m/s."""


def _radial_extent_m(source: Vehicle, depth_m: float) -> float:
    """Radius that holds the jet down to ``depth_m``: three Gaussian widths (S0-2) plus L, m."""
    return 3.0 * depth_m / np.sqrt(source.downwash.c_rad) + source.size_m


def _outermost_radius_m(values: np.ndarray, r_m: np.ndarray, level: float, *, log_r2: bool = False) -> np.ndarray:
    """Largest r (per row of ``values`` (K, M) on ``r_m`` (M,)) where values >= level, interpolated
    at the crossing (linearly, or in (r^2, log value) with ``log_r2``, which is exact for a
    Gaussian radial profile such as S0-2's); 0 where no sample reaches the level, m."""
    above = values >= level
    out = np.zeros(values.shape[0])
    for k in range(values.shape[0]):
        idx = np.nonzero(above[k])[0]
        if idx.size == 0:
            continue
        i = idx[-1]
        if i + 1 >= r_m.size:
            out[k] = r_m[-1]
            continue
        v0, v1 = values[k, i], values[k, i + 1]
        if log_r2 and v1 > 0.0:
            w = (np.log(v0) - np.log(level)) / (np.log(v0) - np.log(v1)) if v0 != v1 else 0.0
            out[k] = np.sqrt(r_m[i] ** 2 + w * (r_m[i + 1] ** 2 - r_m[i] ** 2))
            continue
        w = (v0 - level) / (v0 - v1) if v0 != v1 else 0.0
        out[k] = r_m[i] + w * (r_m[i + 1] - r_m[i])
    return out


def iso_speed_profiles(
    source: Vehicle,
    *,
    depth_m: float,
    levels_mps: tuple[float, ...] | None = None,
    n_dz: int = 60,
    n_r: int = 200,
    field_form: str = "inverse-z",
) -> list[Profile]:
    """Iso-speed profiles of the source's jet down to ``depth_m`` below it (default levels
    ``DEFAULT_ISO_LEVELS_MPS``, m/s)."""
    from proxplan.physics import downwash_speed_mps

    levels_mps = DEFAULT_ISO_LEVELS_MPS if levels_mps is None else levels_mps
    dz = np.linspace(0.0, depth_m, n_dz)
    dz[0] = 1e-3  # the field is zero at and above the rotor plane
    r = np.linspace(0.0, _radial_extent_m(source, depth_m), n_r)
    speed = downwash_speed_mps(source, dz[:, None], (r * r)[None, :], form=field_form)  # (K, M)
    return [Profile(dz, _outermost_radius_m(speed, r, lvl, log_r2=True), f"{lvl:.2f} m/s") for lvl in levels_mps]


def cutoff_profile(
    source: Vehicle,
    target: Vehicle,
    *,
    depth_m: float,
    level: float,
    invalid_rule: str | None = None,
    n_dz: int = 80,
) -> Profile:
    """Cutoff surface of ``target`` under ``source`` at authority-usage ``level``, down to ``depth_m``,
    from the pair's cutoff map (``proxplan.costmaps.map_store.pair_maps``; ``invalid_rule`` for dz <= 3 L,
    default the map's own)."""
    from proxplan.costmaps import pair_maps

    dz = np.linspace(0.0, depth_m, n_dz)
    dz[0] = 1e-3
    r_cut = pair_maps(source, target).cutoff.r_cut_m(dz, level=level, invalid_rule=invalid_rule)
    return Profile(
        dz, np.nan_to_num(np.asarray(r_cut, float), nan=0.0), f"r_cut, usage {level:.2f}, target {target.name}"
    )


ISO_COLOURS = [(230, 60, 40), (250, 160, 40), (70, 150, 230)]
CUTOFF_RGB = (160, 60, 200)


def add_layers(
    scene,
    parent: str,
    source: Vehicle,
    target: Vehicle,
    *,
    depth_m: float,
    level: float,
    invalid_rule: str | None = None,
    show_iso: bool = True,
    show_cutoff: bool = True,
) -> tuple[list, list[Profile]]:
    """Add the iso-speed surfaces and the cutoff surface under node ``parent`` (the source's frame).

    Returns the handles (so they can be toggled and removed) and the profiles drawn.
    """
    handles, profiles = [], []
    for k, prof in enumerate(iso_speed_profiles(source, depth_m=depth_m)):
        v, f = prof.mesh()
        handles.append(
            scene.add_mesh_simple(
                f"{parent}/iso_{k}",
                v,
                f,
                color=ISO_COLOURS[k % len(ISO_COLOURS)],
                opacity=0.18 + 0.07 * k,
                side="double",
                cast_shadow=False,
                receive_shadow=False,
                visible=show_iso,
            )
        )
        profiles.append(prof)
    prof = cutoff_profile(source, target, depth_m=depth_m, level=level, invalid_rule=invalid_rule)
    v, f = prof.mesh()
    handles.append(
        scene.add_mesh_simple(
            f"{parent}/cutoff",
            v,
            f,
            color=CUTOFF_RGB,
            opacity=0.25,
            wireframe=False,
            side="double",
            cast_shadow=False,
            receive_shadow=False,
            visible=show_cutoff,
        )
    )
    profiles.append(prof)
    return handles, profiles
