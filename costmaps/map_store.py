"""Pair maps (cutoff map + wrench table) of a (source, target) pair: build, cache, save, load, ship.

File format (.npz, version :data:`FORMAT_VERSION`, float32 arrays):

* ``format_version`` (int), ``metadata_json`` (str: JSON with the model form and options, every
  parameter of both vehicles (``Vehicle.to_dict()``), ``param_hash``, tool version, levels, rule,
  resolutions, table extents);
* cutoff map: ``dz_m`` (K,), ``r_cut_m`` (K,) at ``default_level``, ``levels`` (M,),
  ``r_cut_levels_m`` (M, K), ``default_level``, ``valid`` (K,), ``invalid_rule``, ``validity_dz_m``,
  ``overlap_radius_m``, ``cutoff_r_grid_m`` (n_r, K), ``cutoff_usage`` (n_r, K);
* wrench table: ``table_xi`` (nx,), ``table_eta`` (ny,), ``table_dz_m`` (nz,), ``table_scale``
  (a_m, b, c_m), ``table_valid`` (nz,), ``table_boundary_usage``, ``table_beyond_dz_usage`` and the
  quadrant xi >= 0, eta >= 0 of ``table_force_z_N``, ``table_torque_x_Nm``, ``table_torque_y_Nm``
  (the rest follows by the model's mirror symmetry, see :mod:`proxplan.costmaps.wrench_table`).

``param_hash`` = SHA-256 of the canonical JSON of both vehicles' parameters (``to_dict()`` without
the free-text ``description``/``sources``), :class:`ModelOptions` and the format version. A map is
reused only when its hash matches the vehicles and options asked for.

Shipped maps live in ``costmaps/data/<source>__<target>.npz`` for every ordered pair of built-in
vehicles; regenerate them with ``proxplan costmap --all --out-dir costmaps/data``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from proxplan.costmaps.cutoff import (
    DEFAULT_CUTOFF_RESOLUTION,
    DEFAULT_INVALID_RULE,
    DEFAULT_LEVEL,
    DEFAULT_LEVELS,
    CutoffMap,
    CutoffResolution,
    build_cutoff_map,
)
from proxplan.costmaps.effects import EffectsKey, effects_key, effects_of_key, map_effects
from proxplan.costmaps.wrench_table import (
    DEFAULT_RESOLUTION,
    LateralScale,
    TableResolution,
    WrenchTable,
    build_wrench_table,
    mirror_quadrant,
)
from proxplan.fileio import UserError, atomic_output
from proxplan.physics import DEFAULT_OPTIONS, Effect, ModelOptions, Vehicle, effects_to_list

FORMAT_VERSION = 1
"""Bump when the .npz layout or the meaning of a stored array changes."""

DATA_DIR = Path(__file__).resolve().parent / "data"
"""Shipped maps of every ordered pair of built-in vehicles."""

_NOT_MAP_INPUTS = (
    "description",
    "sources",
    "kinematic_limits",
    "motor_time_constant_s",
    "tracking",
    "tracking_tube_m",
    "rotor_drag",
    "controller",
)  # not map inputs (how the vehicle flies, not the downwash it makes or meets)


@dataclass(frozen=True, eq=False)
class PairMaps:
    """Cutoff map and wrench table of one (source, target) pair with their metadata dict."""

    cutoff: CutoffMap
    table: WrenchTable
    metadata: dict


def vehicle_parameters(vehicle: Vehicle) -> dict:
    """``vehicle.to_dict()`` without free-text keys: what the maps depend on."""
    return {k: v for k, v in vehicle.to_dict().items() if k not in _NOT_MAP_INPUTS}


def options_dict(options: ModelOptions) -> dict:
    """Model options a pair map depends on (field form, C_D, air density, discretisation) as a plain
    dict. ``stack_shielding`` is left out: it acts only with two or more sources above a target
    (:mod:`proxplan.physics.stack`), never on one source-target pair."""
    out = dataclasses.asdict(options)
    out.pop("stack_shielding", None)
    return out


def effects_list(effects: Sequence[Effect]) -> list[dict]:
    """The effects a map applies (:func:`proxplan.costmaps.effects.map_effects`), ``[{name, params}]``."""
    return effects_to_list(map_effects(effects))


def param_hash(
    source: Vehicle, target: Vehicle, options: ModelOptions = DEFAULT_OPTIONS, effects: Sequence[Effect] = ()
) -> str:
    """SHA-256 (hex) of both vehicles' parameters, the model options, the applied effects with
    their parameters (only when there are some: maps of the base model keep their hash) and the
    format version."""
    payload = {
        "format_version": FORMAT_VERSION,
        "source": vehicle_parameters(source),
        "target": vehicle_parameters(target),
        "options": options_dict(options),
    }
    if map_effects(effects):
        payload["effects"] = effects_list(effects)
    text = json.dumps(payload, sort_keys=True, separators=(",", ":"), allow_nan=False)
    return hashlib.sha256(text.encode()).hexdigest()


def tool_version() -> str:
    """Installed proxplan version, or "unknown"."""
    try:
        from importlib.metadata import version

        return version("proxplan")
    except Exception:  # noqa: BLE001 - not installed (running from a checkout)
        return "unknown"


def shipped_path(source_name: str, target_name: str, data_dir: Path = DATA_DIR) -> Path:
    """Path of the shipped map of a pair (may not exist)."""
    return Path(data_dir) / f"{source_name}__{target_name}.npz"


def build_pair_maps(
    source: Vehicle,
    target: Vehicle,
    *,
    options: ModelOptions = DEFAULT_OPTIONS,
    levels: tuple[float, ...] = DEFAULT_LEVELS,
    default_level: float = DEFAULT_LEVEL,
    invalid_rule: str = DEFAULT_INVALID_RULE,
    cutoff_resolution: CutoffResolution = DEFAULT_CUTOFF_RESOLUTION,
    table_resolution: TableResolution = DEFAULT_RESOLUTION,
    effects: Sequence[Effect] = (),
) -> PairMaps:
    """Compute both maps from the model plus the between-vehicle ``effects`` of a calibrated
    model (:func:`proxplan.costmaps.effects.map_effects`; about 1-2 s per pair)."""
    cutoff = build_cutoff_map(
        source,
        target,
        options=options,
        levels=levels,
        default_level=default_level,
        invalid_rule=invalid_rule,
        resolution=cutoff_resolution,
        effects=effects,
    )
    table = build_wrench_table(source, target, options=options, resolution=table_resolution, effects=effects)
    metadata = {
        "format_version": FORMAT_VERSION,
        "tool_version": tool_version(),
        "param_hash": param_hash(source, target, options, effects),
        "source_name": source.name,
        "target_name": target.name,
        "model": {
            "field_form": options.field_form,
            "options": options_dict(options),
            "effects": effects_list(effects),
        },
        "source": source.to_dict(),
        "target": target.to_dict(),
        "levels": [float(v) for v in cutoff.levels],
        "default_level": cutoff.default_level,
        "invalid_rule": cutoff.invalid_rule,
        "validity_dz_m": cutoff.validity_dz_m,
        "overlap_radius_m": cutoff.overlap_radius_m,
        "cutoff_resolution": dataclasses.asdict(cutoff_resolution),
        "table_resolution": dataclasses.asdict(table_resolution),
        "table_dz_range_m": [float(table.dz_m[0]), float(table.dz_m[-1])],
        "table_boundary_usage": table.boundary_usage,
        "table_beyond_dz_usage": table.beyond_dz_usage,
        "peak_usage_valid_zone": float(cutoff.usage[:, cutoff.valid].max()) if cutoff.valid.any() else 0.0,
    }
    return PairMaps(cutoff=cutoff, table=table, metadata=metadata)


def _atomic_write_npz(path: Path, arrays: dict) -> None:
    with atomic_output(path, suffix=".npz") as tmp:
        with open(tmp, "wb") as handle:
            np.savez_compressed(handle, **arrays)


def save_pair_maps(maps: PairMaps, path: str | Path) -> Path:
    """Write ``maps`` to ``path`` (.npz, float32) atomically (temp file + rename); returns the path."""
    c, t = maps.cutoff, maps.table
    half_x, half_y = t.xi.size // 2, t.eta.size // 2
    f32 = np.float32
    arrays = {
        "format_version": np.array(FORMAT_VERSION),
        "metadata_json": np.array(json.dumps(maps.metadata, sort_keys=True)),
        "dz_m": c.dz_m.astype(np.float64),  # float64: the validity boundary is a node
        "r_cut_m": c.default_r_cut_m.astype(f32),
        "levels": c.levels.astype(f32),
        "r_cut_levels_m": c.r_cut_levels_m.astype(f32),
        "default_level": np.array(c.default_level),
        "valid": c.valid,
        "invalid_rule": np.array(c.invalid_rule),
        "validity_dz_m": np.array(c.validity_dz_m),
        "overlap_radius_m": np.array(c.overlap_radius_m),
        "cutoff_r_grid_m": c.r_grid_m.astype(f32),
        "cutoff_usage": c.usage.astype(f32),
        "table_xi": t.xi.astype(f32),
        "table_eta": t.eta.astype(f32),
        "table_dz_m": t.dz_m.astype(np.float64),
        "table_scale": np.array([t.scale.a_m, t.scale.b, t.scale.c_m]),
        "table_valid": t.valid,
        "table_boundary_usage": np.array(t.boundary_usage),
        "table_beyond_dz_usage": np.array(t.beyond_dz_usage),
        "table_force_z_N": t.force_z_N[half_x:, half_y:].astype(f32),
        "table_torque_x_Nm": t.torque_x_Nm[half_x:, half_y:].astype(f32),
        "table_torque_y_Nm": t.torque_y_Nm[half_x:, half_y:].astype(f32),
    }
    path = Path(path)
    if path.suffix != ".npz":
        raise UserError(f"{path}: output must end in .npz")
    _atomic_write_npz(path, arrays)
    return path


_REQUIRED_KEYS = (
    "format_version", "metadata_json", "dz_m", "levels", "r_cut_levels_m", "default_level", "valid",
    "invalid_rule", "validity_dz_m", "overlap_radius_m", "cutoff_r_grid_m", "cutoff_usage",
    "table_xi", "table_eta", "table_dz_m", "table_scale", "table_valid", "table_force_z_N",
    "table_torque_x_Nm", "table_torque_y_Nm",
)  # fmt: skip


def _differences(stored: dict, expected: dict, prefix: str = "") -> list[str]:
    """Dotted keys (with both values) of every parameter that differs between two nested dicts."""
    found: list[str] = []
    for key in sorted(set(stored) | set(expected)):
        a, b = stored.get(key), expected.get(key)
        if isinstance(a, dict) and isinstance(b, dict):
            found += _differences(a, b, f"{prefix}{key}.")
        elif a != b:
            found.append(f"{prefix}{key} (map {a!r}, expected {b!r})")
    return found


def load_pair_maps(
    path: str | Path,
    *,
    expect_source: Vehicle | None = None,
    expect_target: Vehicle | None = None,
    options: ModelOptions | None = None,
    effects: Sequence[Effect] = (),
) -> PairMaps:
    """Read a map written by :func:`save_pair_maps`.

    With ``expect_source``/``expect_target`` (and ``options``, default the standard model, and
    ``effects``, default none) the stored ``param_hash`` must match them. Raises :class:`UserError` for a missing or unreadable
    file, another format version, or a parameter mismatch, naming the first differing parameter.
    """
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as npz:
            data = {k: npz[k] for k in npz.files}
    except FileNotFoundError:
        raise UserError(f"{path}: no such cost map file") from None
    except Exception as err:  # noqa: BLE001 - corrupt/not an npz
        raise UserError(f"{path}: not a readable cost map (.npz): {err}") from None
    missing = [k for k in _REQUIRED_KEYS if k not in data]
    if "format_version" in data and int(data["format_version"]) != FORMAT_VERSION:
        raise UserError(
            f"{path}: cost map format version {int(data['format_version'])}, this proxplan reads "
            f"version {FORMAT_VERSION}; regenerate it with `proxplan costmap`"
        )
    if missing:
        raise UserError(f"{path}: not a proxplan cost map (missing keys: {', '.join(missing)})")
    metadata = json.loads(str(data["metadata_json"]))
    if expect_source is not None or expect_target is not None:
        if expect_source is None or expect_target is None:
            raise ValueError("give both expect_source and expect_target")
        opts = DEFAULT_OPTIONS if options is None else options
        expected = param_hash(expect_source, expect_target, opts, effects)
        if metadata.get("param_hash") != expected:
            diffs = _differences(
                {
                    "source": {k: v for k, v in metadata.get("source", {}).items() if k not in _NOT_MAP_INPUTS},
                    "target": {k: v for k, v in metadata.get("target", {}).items() if k not in _NOT_MAP_INPUTS},
                    "options": metadata.get("model", {}).get("options", {}),
                    "effects": {"list": metadata.get("model", {}).get("effects", [])},
                },
                {
                    "source": vehicle_parameters(expect_source),
                    "target": vehicle_parameters(expect_target),
                    "options": json.loads(json.dumps(options_dict(opts))),
                    "effects": {"list": json.loads(json.dumps(effects_list(effects)))},
                },
            )
            raise UserError(
                f"{path}: cost map was made for other parameters than "
                f"{expect_source.name} -> {expect_target.name} with these model options "
                f"(differences: {'; '.join(diffs[:4]) or 'format or hash only'}"
                f"{'; ...' if len(diffs) > 4 else ''}); regenerate it with `proxplan costmap`"
            )
    return _maps_from_arrays(data, metadata)


def _maps_from_arrays(data: dict, metadata: dict) -> PairMaps:
    f64 = np.float64
    cutoff = CutoffMap(
        source_name=metadata["source_name"],
        target_name=metadata["target_name"],
        dz_m=data["dz_m"].astype(f64),
        levels=data["levels"].astype(f64),
        r_cut_levels_m=data["r_cut_levels_m"].astype(f64),
        default_level=float(data["default_level"]),
        valid=data["valid"].astype(bool),
        invalid_rule=str(data["invalid_rule"]),
        r_grid_m=data["cutoff_r_grid_m"].astype(f64),
        usage=data["cutoff_usage"].astype(f64),
        validity_dz_m=float(data["validity_dz_m"]),
        overlap_radius_m=float(data["overlap_radius_m"]),
    )
    a_m, b, c_m = (float(v) for v in data["table_scale"])
    table = WrenchTable(
        source_name=metadata["source_name"],
        target_name=metadata["target_name"],
        xi=data["table_xi"].astype(f64),
        eta=data["table_eta"].astype(f64),
        dz_m=data["table_dz_m"].astype(f64),
        scale=LateralScale(a_m=a_m, b=b, c_m=c_m),
        force_z_N=mirror_quadrant(data["table_force_z_N"].astype(f64), 1.0, 1.0),
        torque_x_Nm=mirror_quadrant(data["table_torque_x_Nm"].astype(f64), 1.0, -1.0),
        torque_y_Nm=mirror_quadrant(data["table_torque_y_Nm"].astype(f64), -1.0, 1.0),
        valid=data["table_valid"].astype(bool),
        boundary_usage=float(data.get("table_boundary_usage", 0.0)),
        beyond_dz_usage=float(data.get("table_beyond_dz_usage", 0.0)),
    )
    return PairMaps(cutoff=cutoff, table=table, metadata=metadata)


@lru_cache(maxsize=64)
def _cached_pair_maps(source: Vehicle, target: Vehicle, options: ModelOptions, key: EffectsKey) -> PairMaps:
    effects = effects_of_key(key)
    shipped = shipped_path(source.name, target.name)
    if shipped.exists():
        try:
            return load_pair_maps(shipped, expect_source=source, expect_target=target, options=options, effects=effects)
        except UserError:
            pass  # stale or other parameters (custom/calibrated vehicle or effects): compute
    return build_pair_maps(source, target, options=options, effects=effects)


def pair_maps(
    source: Vehicle, target: Vehicle, *, options: ModelOptions = DEFAULT_OPTIONS, effects: Sequence[Effect] = ()
) -> PairMaps:
    """Maps of a pair: the shipped map when its parameter hash matches, else computed (cached in
    this process). Works for custom and calibrated vehicles and a calibrated model's
    between-vehicle ``effects`` (computed, about 1-2 s per pair)."""
    return _cached_pair_maps(source, target, options, effects_key(map_effects(effects)))
