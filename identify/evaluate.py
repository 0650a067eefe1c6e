"""Score a saved model on flight logs without refitting (``proxplan evaluate``).

The saved model (:mod:`proxplan.physics.model_file`) holds everything identify used for its "after" figure:
calibrated vehicles, model options, kept effects with their parameters, per-type thrust scales, and
under ``model.measurement`` how the disturbance was measured (derivative, window, motor lag and the
per-type PWM*Vbat thrust maps of :mod:`proxplan.identify.thrust_map`). :func:`evaluate_model` measures the
manifest's flights the same way, predicts with the saved model, and reports the RMSE of F_z (world
z force, N) and of the torque vector (N m) against ``no_model`` (the same samples predicted as zero
disturbance), per flight, per vehicle (the manifest's vehicle key) and per region:

* ``below_source`` — some source within r < 3 L horizontally and above (dz > 0); ``free`` — not;
* ``below_within_3L`` — below a source with dz < 3 L (outside the field model's zone, S0 II-A);
  ``below_beyond_3L`` — below sources, all with dz >= 3 L (inside the zone);
* ``stack`` — two or more sources above within r < 3 L.

and per experiment set (the manifest's per-flight ``set``) and per number of sources overhead
(``overhead``: "0", "1", "2+" sources above within r < 3 L).

Vehicles with ``score: false`` are sources only; a manifest whose flights are all ``test`` is valid.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from proxplan.fileio import UserError
from proxplan.identify.data import (
    IdentifyOptions,
    Model,
    Predictions,
    Unit,
    sources_overhead,
)
from proxplan.identify.flightlog import Manifest
from proxplan.identify.loading import load_units, measurement_summary
from proxplan.identify.manifest import load_manifest
from proxplan.identify.measure import DERIVATIVES, MeasureOptions
from proxplan.identify.motor_check import check_loaded
from proxplan.identify.spread import BandAccumulator, interval_half_width_N, slow_part
from proxplan.identify.strata import AUTHORITY_STATES, authority_masks
from proxplan.identify.thrust_map import ThrustMap
from proxplan.physics import CalibratedModel, ResidualSpread, one_blas_thread

SPLITS = ("test", "validation", "train", "all")
REGIONS = ("free", "below_source", "below_within_3L", "below_beyond_3L", "stack")


# ------------------------------------------------------------------------------ model <-> identify


def measurement_dict(options: MeasureOptions, thrust_maps: Mapping[str, ThrustMap]) -> dict[str, Any]:
    """The ``model.measurement`` mapping saved with a model (plain data)."""
    return {
        "derivative": options.derivative,
        "window_s": float(options.window_s),
        "polyorder": int(options.polyorder),
        "motor_time_constant_s": options.motor_time_constant_s,
        "motor_lag": bool(options.motor_lag),
        "command_interpolation": {t: float(p) for t, p in options.command_interpolation_by_type},
        "thrust_maps": {t: m.to_dict() for t, m in thrust_maps.items()},
    }


def measurement_from_model(
    model: CalibratedModel, label: str
) -> tuple[MeasureOptions, dict[str, ThrustMap], list[str]]:
    """Measurement options and thrust maps of a saved model; notes when it holds none."""
    where = f"{label}: model.measurement"
    raw = dict(model.measurement)
    if not raw:
        note = (f"{where}: missing (a model not written by identify --save-model of this version): measured "
                "with the default derivative and the logged u[N] (saturated motors not corrected)")  # fmt: skip
        return MeasureOptions(), {}, [note]
    unknown = sorted(
        set(raw)
        - {
            "derivative",
            "window_s",
            "polyorder",
            "motor_time_constant_s",
            "motor_lag",
            "command_interpolation",
            "thrust_maps",
        }  # fmt: skip
    )
    if unknown:
        raise UserError(f"{where}: unknown key {unknown[0]!r}")
    derivative = raw.get("derivative", "savgol")
    if derivative not in DERIVATIVES:
        raise UserError(f"{where}.derivative: expected one of {', '.join(DERIVATIVES)}, got {derivative!r}")
    try:
        tau = raw.get("motor_time_constant_s")
        options = MeasureOptions(
            derivative=derivative,
            window_s=float(raw.get("window_s", 0.15)),
            polyorder=int(raw.get("polyorder", 2)),
            motor_time_constant_s=None if tau is None else float(tau),
            motor_lag=bool(raw.get("motor_lag", False)),  # models saved before the key: no lag compensation
            command_interpolation_by_type=tuple(  # models saved before the key: held (p = 0)
                (str(t), float(p)) for t, p in dict(raw.get("command_interpolation") or {}).items()
            ),
        )
    except (TypeError, ValueError):
        raise UserError(
            f"{where}: window_s, polyorder, motor_time_constant_s, command_interpolation: expected numbers "
            "(command_interpolation: a mapping TYPE: p)"
        ) from None
    maps_raw = raw.get("thrust_maps") or {}
    if not isinstance(maps_raw, Mapping):
        raise UserError(f"{where}.thrust_maps: expected a mapping TYPE: {{coef, x_max_V}}")
    maps = {str(t): ThrustMap.from_dict(d, f"{where}.thrust_maps.{t}") for t, d in maps_raw.items()}
    return options, maps, []


def saved_model(
    model: Model,
    measure: MeasureOptions,
    thrust_maps: Mapping[str, ThrustMap],
    spread: ResidualSpread | None = None,
) -> CalibratedModel:
    """The :class:`proxplan.physics.CalibratedModel` of an identify model plus how it was measured and the
    residual spread it cannot predict."""
    return CalibratedModel(
        vehicles=dict(model.vehicles),
        options=model.options,
        effects=tuple(model.effects),
        thrust_scales={k: float(v) for k, v in model.thrust_scale.items()},
        measurement=measurement_dict(measure, thrust_maps),
        residual_spread=spread,
    )


# ------------------------------------------------------------------------------ scoring


OVERHEAD_COUNTS = ("0", "1", "2+")
"""Labels of the per-sources-overhead report."""
GRAMS_PER_N = 1000.0 / 9.80665
"""Grams-force per newton (the paper's unit of the disturbance), g/N."""


def overhead_masks(u: Unit, vehicles: Mapping[str, Any]) -> dict[str, np.ndarray]:
    """Per sample of ``u``, one mask per :data:`OVERHEAD_COUNTS` label."""
    above, _ = sources_overhead(u, vehicles)
    return {"0": above == 0, "1": above == 1, "2+": above >= 2}


def region_masks(u: Unit, vehicles: Mapping[str, Any]) -> dict[str, np.ndarray]:
    """Per sample of ``u``, the :data:`REGIONS` masks (see the module docstring)."""
    above, near = sources_overhead(u, vehicles)
    below = above > 0
    return {"free": ~below, "below_source": below, "below_within_3L": near, "below_beyond_3L": below & ~near,
            "stack": above >= 2}  # fmt: skip


@dataclass
class _Acc:
    """Running sums of squared errors (model and no model) over samples."""

    n: int = 0
    sse_fz: float = 0.0
    sse_tq: float = 0.0
    sse_fz0: float = 0.0
    sse_tq0: float = 0.0

    def add(self, dfz: np.ndarray, dtq: np.ndarray, fz0: np.ndarray, tq0: np.ndarray) -> None:
        self.n += int(dfz.size)
        self.sse_fz += float(np.sum(dfz**2))
        self.sse_tq += float(np.sum(dtq**2))
        self.sse_fz0 += float(np.sum(fz0**2))
        self.sse_tq0 += float(np.sum(tq0**2))

    def rmse(self, sse: float) -> float | None:
        return float(np.sqrt(sse / self.n)) if self.n else None


@dataclass(frozen=True)
class EvaluationResult:
    split: str
    overall: _Acc
    flights: dict[str, _Acc]
    per_vehicle: dict[str, _Acc]
    regions: dict[str, _Acc]
    sets: dict[str, _Acc]  # per experiment set (manifest flight key ``set``)
    overhead: dict[str, _Acc]  # per OVERHEAD_COUNTS label
    set_overhead: dict[str, dict[str, _Acc]]  # set -> overhead label -> errors
    authority: dict[str, _Acc]  # per AUTHORITY_STATES label
    set_authority: dict[str, dict[str, _Acc]]  # set -> authority state -> errors
    n_rows: int
    exclusions: dict
    notes: list[str]
    measurement: dict
    units: list[Unit] = field(default_factory=list)
    model: Model | None = None
    motor_lag_check: dict = field(default_factory=dict)  # proxplan.identify.motor_check (warnings inside)
    bands: dict[str, BandAccumulator] = field(default_factory=dict)  # "all" and per set: below / above 1 Hz, coverage

    def to_json(self) -> dict[str, Any]:
        o = self.overall
        return {
            "rmse_fz_N": o.rmse(o.sse_fz),
            "rmse_fz_g": _short(o)["rmse_fz_g"],
            "ratio_fz": _short(o)["ratio_fz"],
            "rmse_torque_Nm": o.rmse(o.sse_tq),
            "n_samples": o.n,
            "n_rows": self.n_rows,
            "scored_fraction": o.n / self.n_rows if self.n_rows else None,
            "no_model": {
                "rmse_fz_N": o.rmse(o.sse_fz0),
                "rmse_fz_g": _short(o)["no_model_rmse_fz_g"],
                "rmse_torque_Nm": o.rmse(o.sse_tq0),
            },
            "flights": {k: _short(a) for k, a in self.flights.items()},
            "per_vehicle": {k: _short(a) for k, a in self.per_vehicle.items()},
            "regions": {k: _short(a) for k, a in self.regions.items()},
            "sets": {k: _short(a) for k, a in self.sets.items()},
            "overhead": {k: _short(a) for k, a in self.overhead.items()},
            "set_overhead": {k: {c: _short(a) for c, a in d.items()} for k, d in self.set_overhead.items()},
            "authority": _shares(self.authority, o),
            "set_authority": {k: _shares(d, _total(d)) for k, d in self.set_authority.items()},
            "split": self.split,
            "exclusions": self.exclusions,
            "measurement": self.measurement,
            "notes": list(self.notes),
            "motor_lag_check": self.motor_lag_check,
            "warnings": list(self.motor_lag_check.get("warnings", [])),
            "bands": {k: b.to_json(GRAMS_PER_N) for k, b in self.bands.items()},
        }


def _short(a: _Acc) -> dict[str, Any]:
    fz, fz0 = a.rmse(a.sse_fz), a.rmse(a.sse_fz0)
    ratio = fz / fz0 if fz is not None and fz0 else None
    return {"rmse_fz_N": fz, "no_model_rmse_fz_N": fz0, "ratio_fz": ratio, "n_samples": a.n,
            "rmse_fz_g": None if fz is None else fz * GRAMS_PER_N,
            "no_model_rmse_fz_g": None if fz0 is None else fz0 * GRAMS_PER_N}  # fmt: skip


def _shares(groups: Mapping[str, _Acc], total: _Acc) -> dict[str, dict[str, Any]]:
    """:func:`_short` of each group plus its share of the samples and of the squared F_z error."""
    return {k: _short(a) | {"share_of_samples": a.n / total.n if total.n else None,
                            "share_of_sq_error": a.sse_fz / total.sse_fz if total.sse_fz else None}
            for k, a in groups.items()}  # fmt: skip


def _total(groups: Mapping[str, _Acc]) -> _Acc:
    out = _Acc()
    for a in groups.values():
        out.n += a.n
        out.sse_fz += a.sse_fz
        out.sse_fz0 += a.sse_fz0
    return out


def _rows(e: Mapping[str, Any]) -> int:
    keys = ("kept_samples", "nan_rows", "short_segment_samples", "ground_samples", "outside_overlap_samples")
    return int(sum(e[k] for k in keys))


@one_blas_thread
def evaluate_model(
    manifest: Manifest | str | Path,
    model: CalibratedModel,
    *,
    split: str = "test",
    label: str = "<model>",
    progress: bool = False,
) -> EvaluationResult:
    """Score ``model`` on the ``split`` flights of ``manifest`` (no fitting; see the module docstring)."""
    if split not in SPLITS:
        raise UserError(f"--split: expected one of {', '.join(SPLITS)}, got {split!r}")
    if not isinstance(manifest, Manifest):
        manifest = load_manifest(manifest, require_train_and_test=False)
    measure, maps, notes = measurement_from_model(model, label)
    chosen = [f for f in manifest.flights if split == "all" or f.split == split]
    if not chosen:
        raise UserError(f"{manifest.path}: flights: no {split} flight to evaluate (use --split train|test|all)")
    if not any(v.score for f in chosen for v in f.vehicles):
        raise UserError(f"{manifest.path}: flights: every {split} vehicle says 'score: false'; nothing to score")
    sub = replace(manifest, flights=tuple(chosen))
    data = load_units(
        sub,
        options=IdentifyOptions(measure=measure, progress=progress),
        thrust_maps=maps,
        thrust_coefficient_samples=False,
    )
    notes += data.notes
    missing = sorted(set(data.types) - set(model.vehicles))
    if missing:
        notes.append(f"{label}: vehicles: no calibrated {', '.join(missing)}; the manifest's type used as given")
    vehicles = {t: model.vehicles.get(t, v) for t, v in data.types.items()}
    m = Model(vehicles=vehicles, thrust_scale=dict(model.thrust_scales), effects=tuple(model.effects),
              options=model.options)  # fmt: skip
    units = [u for u in data.units if u.scored and len(u)]
    overall = _Acc()
    flights: dict[str, _Acc] = {}
    per_vehicle: dict[str, _Acc] = {}
    regions = {r: _Acc() for r in REGIONS}
    set_of = {f.name: f.set for f in chosen}
    sets: dict[str, _Acc] = {}
    overhead = {c: _Acc() for c in OVERHEAD_COUNTS}
    set_overhead: dict[str, dict[str, _Acc]] = {}
    authority = {c: _Acc() for c in AUTHORITY_STATES}
    set_authority: dict[str, dict[str, _Acc]] = {}
    bands = {"all": BandAccumulator()}
    spread = model.residual_spread
    if spread is None:
        notes.append(
            f"{label}: model.residual_spread: missing (a model saved before it): no 90 % interval, no coverage"
        )
    pred = Predictions()
    for u in units:
        f, t = pred(u, m)
        dfz, dtq = u.force_N[:, 2] - f[:, 2], np.linalg.norm(u.torque_Nm - t, axis=1)
        slow = slow_part(dfz, u.t_s)
        half = interval_half_width_N(u, m, spread, pred) if spread is not None else None
        for acc_b in (bands["all"], bands.setdefault(set_of[u.flight], BandAccumulator())):
            acc_b.add(dfz, slow, half, u.flight)
        fz0, tq0 = u.force_N[:, 2], np.linalg.norm(u.torque_Nm, axis=1)
        for acc in (overall, flights.setdefault(u.flight, _Acc()), per_vehicle.setdefault(u.name, _Acc())):
            acc.add(dfz, dtq, fz0, tq0)
        sets.setdefault(set_of[u.flight], _Acc()).add(dfz, dtq, fz0, tq0)
        for r, mask in region_masks(u, vehicles).items():
            regions[r].add(dfz[mask], dtq[mask], fz0[mask], tq0[mask])
        per_set = set_overhead.setdefault(set_of[u.flight], {c: _Acc() for c in OVERHEAD_COUNTS})
        for c, mask in overhead_masks(u, vehicles).items():
            for acc in (overhead[c], per_set[c]):
                acc.add(dfz[mask], dtq[mask], fz0[mask], tq0[mask])
        per_set_auth = set_authority.setdefault(set_of[u.flight], {c: _Acc() for c in AUTHORITY_STATES})
        for c, mask in authority_masks(u, vehicles).items():
            for acc in (authority[c], per_set_auth[c]):
                acc.add(dfz[mask], dtq[mask], fz0[mask], tq0[mask])
    n_rows = sum(_rows(e) for per in data.exclusions.values() for e in per.values() if e["scored"])
    return EvaluationResult(
        split=split, overall=overall, flights=flights, per_vehicle=per_vehicle, regions=regions, sets=sets,
        overhead=overhead, set_overhead=set_overhead, authority=authority, set_authority=set_authority, n_rows=n_rows,
        exclusions=data.exclusions, notes=notes, measurement=measurement_summary(data.thrust_maps, data.exclusions, []),
        units=units, model=m, motor_lag_check=check_loaded(data, motor_thrust=manifest.motor_thrust, options=measure),
        bands=bands,
    )  # fmt: skip
