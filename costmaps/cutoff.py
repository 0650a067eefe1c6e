"""Disturbance-cutoff map: horizontal separation r_cut(dz) beyond which authority usage stays low.

Frames and signs: world z up; the target sits at p_target - p_source = (r cos phi, r sin phi, -dz),
dz > 0 when the target is below the source. Both vehicles hover level with aligned axes.

For every vertical separation dz on a grid the target's authority usage (DESIGN.md section 3, from
:func:`proxplan.physics.disturbance.disturbance_wrench` and :func:`proxplan.physics.authority.authority_usage`) is
evaluated on a radial grid and maximised over the azimuth phi in [0, pi/4] (the X-frame target and
the axisymmetric jet make every other azimuth a mirror image of one in that sector). The map keeps
this usage grid U(r, dz), so ``r_cut_m`` answers any threshold ``level``: r_cut is the *outermost*
radius where U >= level (linear interpolation between radial nodes), so for r > r_cut the usage
stays below the level. Between dz nodes the larger of the two bracketing values is taken
(conservative where a contour closes between nodes and r_cut drops to 0).

Invalid zone. The field model holds for dz > 3 L_source (S0 II-A). For 0 < dz <= 3 L_source the
cutoff is never silently zero; the rule is one of :data:`INVALID_RULES`:

``conservative`` (default)
    r_cut = max(model value at this dz, r_cut at the validity boundary dz = 3 L_source,
    overlap radius), where the overlap radius = (arm + propeller radius) of the source + the same of
    the target: closer than that, the rotor disks overlap geometrically.
``model``
    the model's extrapolated numbers as they are.
``forbid``
    the whole invalid cylinder up to the forbid radius = max(overlap radius, largest r_cut anywhere
    on the grid at this level, model or not).

Above the source (dz <= 0) there is no downwash and r_cut = 0. Deeper than the grid (dz > dz_max) the
last value is held.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from proxplan.costmaps.effects import map_effects, pair_wrench
from proxplan.costmaps.wrench_table import USAGE_FLOOR, LateralScale, default_dz_max_m, target_half_extent_m
from proxplan.physics import DEFAULT_OPTIONS, VALIDITY_FACTOR_L, Effect, ModelOptions, Vehicle, authority_usage

INVALID_RULES = ("conservative", "model", "forbid")
DEFAULT_INVALID_RULE = "conservative"
DEFAULT_LEVELS = (0.02, 0.05, 0.1, 0.25, 0.5)
"""Stored authority-usage thresholds, -. Low levels matter for light sources over heavy targets
(small-quad over large-quad peaks near 0.04 in the valid zone); 0.5 is DESIGN's default
``limits.authority_fraction``."""
DEFAULT_LEVEL = 0.5


@dataclass(frozen=True)
class CutoffResolution:
    """Grid of the usage map.

    ``n_dz`` nodes dz = dz_max u^``dz_power`` (u uniform in [0, 1], dense near the source; dz_max
    None = max(6 m, 15 L_source)); ``n_r`` radial nodes r = rho S(dz), rho uniform in [0, 1], with
    the jet-following half-width S(dz) of :class:`proxplan.costmaps.wrench_table.LateralScale` widened by
    ``lateral_widths``; ``n_azimuth`` azimuths in [0, pi/4].
    """

    n_dz: int = 96
    n_r: int = 121
    n_azimuth: int = 7
    dz_power: float = 1.6
    lateral_widths: float = 3.5
    dz_max_m: float | None = None

    def __post_init__(self) -> None:
        if self.n_dz < 8 or self.n_r < 8 or self.n_azimuth < 2:
            raise ValueError("CutoffResolution needs n_dz >= 8, n_r >= 8 and n_azimuth >= 2")
        if self.dz_max_m is not None and not self.dz_max_m > 0.0:
            raise ValueError(f"dz_max_m must be > 0, got {self.dz_max_m}")


DEFAULT_CUTOFF_RESOLUTION = CutoffResolution()


def _check_level(level: float) -> float:
    level = float(level)
    if not (math.isfinite(level) and level > 0.0):
        raise ValueError(f"authority-usage level must be a positive number, got {level!r}")
    return level


def r_cut_from_usage(r_grid_m: np.ndarray, usage: np.ndarray, level: float) -> np.ndarray:
    """Outermost radius (K,) where usage (n_r, K) on radii r_grid_m (n_r, K) reaches ``level``, m.

    Linear interpolation between the last node at or above the level and the next one; 0 where no
    node reaches it; the outermost node where the last node is still at or above it.
    """
    above = usage >= level
    n_r = usage.shape[0]
    any_above = above.any(axis=0)
    last = n_r - 1 - np.argmax(above[::-1], axis=0)  # (K,) index of the outermost node >= level
    cols = np.arange(usage.shape[1])
    nxt = np.minimum(last + 1, n_r - 1)
    u0, u1 = usage[last, cols], usage[nxt, cols]
    r0, r1 = r_grid_m[last, cols], r_grid_m[nxt, cols]
    with np.errstate(divide="ignore", invalid="ignore"):
        frac = np.where(u0 > u1, (u0 - level) / (u0 - u1), 0.0)
    r = r0 + np.clip(frac, 0.0, 1.0) * (r1 - r0)
    r = np.where(last == n_r - 1, r0, r)
    return np.where(any_above, r, 0.0)


@dataclass(frozen=True, eq=False)
class CutoffMap:
    """r_cut(dz) of a (source, target) pair at several authority-usage levels, plus the usage grid.

    Arrays: ``dz_m`` (K,) vertical separation, positive = target below, m; ``levels`` (M,) stored
    thresholds, -; ``r_cut_levels_m`` (M, K) cutoff radii with ``invalid_rule`` applied, m;
    ``valid`` (K,) dz > 3 L_source; ``r_grid_m`` (n_r, K) radial nodes per dz, m; ``usage`` (n_r, K)
    authority usage maximised over azimuth, -. ``validity_dz_m`` = 3 L_source, m;
    ``overlap_radius_m`` = sum of both vehicles' arm + propeller radius, m.
    """

    source_name: str
    target_name: str
    dz_m: np.ndarray
    levels: np.ndarray
    r_cut_levels_m: np.ndarray
    default_level: float
    valid: np.ndarray
    invalid_rule: str
    r_grid_m: np.ndarray
    usage: np.ndarray
    validity_dz_m: float
    overlap_radius_m: float

    def _raw_r_cut(self, level: float) -> np.ndarray:
        """Model r_cut at the grid's dz nodes (K,), no invalid-zone rule, m."""
        return r_cut_from_usage(self.r_grid_m, self.usage, level)

    def r_cut_m(self, dz_m: np.ndarray, *, level: float | None = None, invalid_rule: str | None = None) -> np.ndarray:
        """Cutoff radius (same shape as ``dz_m``) at authority-usage ``level`` (any positive value;
        default ``default_level``), m. ``invalid_rule`` overrides the map's rule for
        0 < dz <= 3 L_source. 0 where dz <= 0 (target above the source: no downwash)."""
        level = _check_level(self.default_level if level is None else level)
        rule = self.invalid_rule if invalid_rule is None else invalid_rule
        if rule not in INVALID_RULES:
            raise ValueError(f"invalid_rule must be one of {INVALID_RULES}, got {rule!r}")
        dz = np.asarray(dz_m, dtype=float)
        raw = self._raw_r_cut(level)
        r = _bracket_max(self.dz_m, raw, dz)
        invalid = (dz > 0.0) & (dz <= self.validity_dz_m)
        if rule == "conservative":
            at_boundary = float(_bracket_max(self.dz_m, raw, np.array(self.validity_dz_m)))
            floor = max(at_boundary, self.overlap_radius_m)
            r = np.where(invalid, np.maximum(r, floor), r)
        elif rule == "forbid":
            radius = max(self.overlap_radius_m, float(raw.max()))
            r = np.where(invalid, radius, r)
        return np.where(dz > 0.0, r, 0.0)

    @property
    def default_r_cut_m(self) -> np.ndarray:
        """r_cut at ``default_level`` on the grid (K,), m (the ``r_cut_m`` array of the .npz)."""
        return self.r_cut_m(self.dz_m)


def _bracket_max(nodes_m: np.ndarray, values: np.ndarray, dz_m: np.ndarray) -> np.ndarray:
    """Conservative lookup between dz nodes: the larger of the two bracketing node values (the value
    itself on a node; the last value beyond the last node). Linear interpolation would cut corners
    where a usage contour closes between two nodes (r_cut dropping to 0)."""
    k = np.clip(np.searchsorted(nodes_m, dz_m, side="right") - 1, 0, nodes_m.size - 1)
    upper = np.minimum(k + 1, nodes_m.size - 1)
    on_node = np.asarray(dz_m) == nodes_m[k]
    below_grid = np.asarray(dz_m) < nodes_m[0]
    return np.where(on_node | below_grid, values[k], np.maximum(values[k], values[upper]))


def cutoff_dz_grid_m(source: Vehicle, resolution: CutoffResolution) -> np.ndarray:
    """dz nodes (K,) of the usage grid, m; always includes the validity boundary 3 L_source."""
    dz_max = resolution.dz_max_m or default_dz_max_m(source)
    dz = dz_max * np.linspace(0.0, 1.0, resolution.n_dz) ** resolution.dz_power
    boundary = VALIDITY_FACTOR_L * source.size_m
    if boundary < dz_max:
        dz[np.argmin(np.abs(dz[1:] - boundary)) + 1] = boundary
    return np.sort(dz)


def usage_grid(
    source: Vehicle,
    target: Vehicle,
    *,
    options: ModelOptions = DEFAULT_OPTIONS,
    resolution: CutoffResolution = DEFAULT_CUTOFF_RESOLUTION,
    effects: Sequence[Effect] = (),
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Usage maximised over azimuth on the (r, dz) grid, with the between-vehicle ``effects``
    that keep the jet axisymmetric (:func:`proxplan.costmaps.effects.map_effects`).

    Returns dz_m (K,), r_grid_m (n_r, K) and usage (n_r, K); dz = 0 holds the limit from below.
    """
    dz = cutoff_dz_grid_m(source, resolution)
    scale = LateralScale.for_pair(source, target, resolution.lateral_widths)
    rho = np.linspace(0.0, 1.0, resolution.n_r)
    r_grid = rho[:, None] * scale.half_width_m(dz)[None, :]  # (n_r, K)
    phi = np.linspace(0.0, 0.25 * math.pi, resolution.n_azimuth)
    dz_eval = np.maximum(dz, 1e-6 * source.size_m)
    rr = r_grid[:, :, None]
    offsets = np.stack(
        np.broadcast_arrays(rr * np.cos(phi), rr * np.sin(phi), -dz_eval[None, :, None]), axis=-1
    ).reshape(-1, 3)
    force, torque = pair_wrench(source, target, offsets, options, map_effects(effects))
    usage = authority_usage(target, force, torque)
    usage = usage.reshape(resolution.n_r, dz.size, resolution.n_azimuth).max(axis=2)
    return dz, r_grid, usage


def build_cutoff_map(
    source: Vehicle,
    target: Vehicle,
    *,
    options: ModelOptions = DEFAULT_OPTIONS,
    levels: tuple[float, ...] = DEFAULT_LEVELS,
    default_level: float = DEFAULT_LEVEL,
    invalid_rule: str = DEFAULT_INVALID_RULE,
    resolution: CutoffResolution = DEFAULT_CUTOFF_RESOLUTION,
    effects: Sequence[Effect] = (),
) -> CutoffMap:
    """Compute the usage grid and the cutoff radii at ``levels`` (sorted, each > 0)."""
    if invalid_rule not in INVALID_RULES:
        raise ValueError(f"invalid_rule must be one of {INVALID_RULES}, got {invalid_rule!r}")
    levels_arr = np.array(sorted({_check_level(v) for v in levels}), dtype=float)
    if levels_arr.size == 0:
        raise ValueError("at least one level is needed")
    default_level = _check_level(default_level)
    if min(levels_arr) < USAGE_FLOOR:
        raise ValueError(f"levels below {USAGE_FLOOR} are not resolved by the grid extent")
    dz, r_grid, usage = usage_grid(source, target, options=options, resolution=resolution, effects=effects)
    partial = CutoffMap(
        source_name=source.name,
        target_name=target.name,
        dz_m=dz,
        levels=levels_arr,
        r_cut_levels_m=np.zeros((levels_arr.size, dz.size)),
        default_level=default_level,
        valid=dz > VALIDITY_FACTOR_L * source.size_m,
        invalid_rule=invalid_rule,
        r_grid_m=r_grid,
        usage=usage,
        validity_dz_m=VALIDITY_FACTOR_L * source.size_m,
        overlap_radius_m=target_half_extent_m(source) + target_half_extent_m(target),
    )
    rows = np.array([partial.r_cut_m(dz, level=lv) for lv in levels_arr])
    return _replace(partial, r_cut_levels_m=rows)


def _replace(cmap: CutoffMap, **changes) -> CutoffMap:
    import dataclasses

    return dataclasses.replace(cmap, **changes)
