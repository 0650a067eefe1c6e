"""``proxplan identify`` pipeline: measure -> predict -> calibrate -> residuals -> effects -> report.

Stages (DESIGN.md section 6):

1. Load every flight of the manifest (:mod:`costmaps.flightlog`), clean it and measure the disturbance
   on every vehicle (:mod:`costmaps.measure`, S0-11, S0-13 + gyroscopic term).
2. Predict it with the model: :func:`costmaps.effects.total_wrench`, i.e. the base model
   (:func:`costmaps.disturbance.disturbance_wrench`) summed over all other vehicles of the flight at
   their logged relative positions (interpolated onto the target's own clock), plus effects.
3. Calibrate on TRAIN flights only (:mod:`costmaps.calibrate`): per source type c_ax, z0_m, c_rad;
   per target type b_v; jointly with a per-type thrust scale s as a nuisance parameter (logged motor
   thrusts off by a factor put (s - 1) sum(f_i) z_B into the measured force), so that a
   thrust-calibration error does not distort the aerodynamic parameters. Fitted on F_z (world z
   force), the quantity the model predicts best. The scales are then dropped: a thrust correction is
   kept only if the ``thrust_bias`` candidate (global bias + per-type scales) earns it on test data.
4. Residual analysis (:mod:`costmaps.residuals`).
5. Effects: each candidate of :data:`costmaps.effects.EFFECT_NAMES` is fitted on train flights on top
   of the calibrated model (vehicle parameters frozen) and scored on TEST flights; the one that
   cuts the test RMSE of F_z or of the yaw torque most (by at least ``min_gain``, without making the
   other worse by more than 1 %) is kept, and the search repeats with the rest (greedy).
6. Errors before (model as given) and after (calibrated + kept effects) on test flights.

Fits use at most ``max_fit_samples`` train samples and scoring ``max_eval_samples`` test samples
(uniform strides); the before/after figures use every test sample.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from costmaps.calibrate import CalibrationResult, ParamSpec, apply_vehicle_parameters, fit_parameters, vehicle_param_specs
from costmaps.disturbance import ModelOptions, VALIDITY_FACTOR_L
from costmaps.effects import EFFECT_NAMES, PARAMETERS, Effect, EffectInputs, SourceSample, base_wrench, effect_wrench
from costmaps.errors import UserError
from costmaps.flightlog import Flight, Manifest, interpolate_position_m, load_flight, load_manifest
from costmaps.measure import MeasureOptions, measure_log
from costmaps.residuals import correlate, sample_features
from costmaps.vehicles import Vehicle


@dataclass(frozen=True)
class IdentifyOptions:
    """Options of the identification pipeline."""

    measure: MeasureOptions = MeasureOptions()
    field_form: str = "inverse-z"  # form of (S0-1) used for prediction
    calibrate: bool = True
    effects: tuple[str, ...] = EFFECT_NAMES  # candidates to try
    min_gain: float = 0.05  # relative cut of a test RMSE an effect must bring to be kept, -
    max_fit_samples: int = 2000  # train samples of the calibration fit
    max_effect_fit_samples: int = 1000  # train samples per candidate-effect fit
    max_eval_samples: int = 10000  # test samples per candidate score
    max_effects: int = 3  # at most this many effects are kept
    progress: bool = False  # tqdm bars on stderr


@dataclass(frozen=True)
class Unit:
    """One vehicle of one flight, N cleaned samples, ready for prediction."""

    flight: str
    split: str
    name: str  # vehicle name in the flight (e.g. cf51)
    type: str  # vehicle type
    t_s: np.ndarray  # (N,) own clock, s
    velocity_mps: np.ndarray  # (N, 3) world
    height_above_ground_m: np.ndarray  # (N,)
    thrust_z_N: np.ndarray  # (N,) sum of logged motor thrusts times (z_B)_z, N
    source_types: tuple[str, ...]
    source_offsets_m: tuple[np.ndarray, ...]  # each (N, 3) p_target - p_source, world
    force_N: np.ndarray  # (N, 3) measured, world
    torque_Nm: np.ndarray  # (N, 3) measured, world
    thrust: Any = None  # costmaps.thrust_rls.ThrustSamples of the full unit (None after take)

    def take(self, idx: np.ndarray) -> "Unit":
        return replace(
            self,
            t_s=self.t_s[idx],
            velocity_mps=self.velocity_mps[idx],
            height_above_ground_m=self.height_above_ground_m[idx],
            thrust_z_N=self.thrust_z_N[idx],
            source_offsets_m=tuple(o[idx] for o in self.source_offsets_m),
            force_N=self.force_N[idx],
            torque_Nm=self.torque_Nm[idx],
            thrust=None,
        )

    def __len__(self) -> int:
        return len(self.t_s)


@dataclass(frozen=True)
class Model:
    """Vehicles by type, per-type thrust scales and effects: everything a prediction needs."""

    vehicles: Mapping[str, Vehicle]
    thrust_scale: Mapping[str, float] = field(default_factory=dict)
    effects: tuple[Effect, ...] = ()
    options: ModelOptions = ModelOptions()


def unit_inputs(unit: Unit, model: Model) -> EffectInputs:
    return EffectInputs(
        target=model.vehicles[unit.type],
        height_above_ground_m=unit.height_above_ground_m,
        velocity_mps=unit.velocity_mps,
        sources=tuple(SourceSample(model.vehicles[t], o) for t, o in zip(unit.source_types, unit.source_offsets_m)),
        options=model.options,
    )


def predict(unit: Unit, model: Model, *, base: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Predicted measured wrench (force (N, 3) N, torque (N, 3) N m, world) of ``unit``.

    ``base`` may pass a precomputed base wrench for the same vehicles (saves the model call).
    """
    inputs = unit_inputs(unit, model)
    force, torque = (base[0].copy(), base[1].copy()) if base is not None else base_wrench(inputs)
    for eff in model.effects:
        f, t = effect_wrench(eff, inputs)
        force += f
        torque += t
    force[:, 2] += (model.thrust_scale.get(unit.type, 1.0) - 1.0) * unit.thrust_z_N
    return force, torque


# ------------------------------------------------------------------------------ loading + measuring


def load_units(manifest: Manifest, *, options: IdentifyOptions = IdentifyOptions()) -> tuple[list[Unit], dict, dict[str, Vehicle]]:
    """Load, check and measure every flight; returns units, exclusions per flight/vehicle, vehicles by type."""
    from scipy.spatial.transform import Rotation

    from costmaps.thrust_rls import thrust_samples
    from costmaps.vehicle_yaml import load_vehicle_file, resolve_vehicle

    custom = load_vehicle_file(manifest.vehicles_file) if manifest.vehicles_file else None
    types: dict[str, Vehicle] = {}
    units, exclusions = [], {}
    flights = manifest.flights
    bar = _bar(flights, "load+measure", options.progress)
    for entry in bar:
        vehicles = {}
        for v in entry.vehicles:
            vehicles[v.name] = types.setdefault(v.type, resolve_vehicle(v.type, custom, where=f"{manifest.path}: flight {entry.name}: {v.name}.type"))
        flight: Flight = load_flight(entry, vehicles, options=manifest.quality)
        exclusions[entry.name] = {n: e.to_dict() | {"kept_samples": len(flight.logs[n])} for n, e in flight.exclusions.items()}
        types_of = {v.name: v.type for v in entry.vehicles}
        for v in entry.vehicles:
            log = flight.logs[v.name]
            meas = measure_log(vehicles[v.name], log, options=options.measure)
            z_b = Rotation.from_quat(log.quat_xyzw).apply(np.array([0.0, 0.0, 1.0]))
            others = [o for o in entry.vehicles if o.name != v.name]
            units.append(
                Unit(
                    flight=entry.name,
                    split=entry.split,
                    name=v.name,
                    type=v.type,
                    t_s=log.t_s,
                    velocity_mps=log.velocity_mps,
                    height_above_ground_m=log.position_m[:, 2] - v.ground_z_m,
                    thrust_z_N=log.motor_thrust_N.sum(axis=1) * z_b[:, 2],
                    source_types=tuple(types_of[o.name] for o in others),
                    source_offsets_m=tuple(log.position_m - interpolate_position_m(flight.logs[o.name], log.t_s) for o in others),
                    force_N=meas.force_N,
                    torque_Nm=meas.torque_Nm,
                    thrust=thrust_samples(vehicles[v.name], log.quat_xyzw, log.accel_mps2, log.velocity_mps, log.motor_thrust_N),
                )
            )
    return units, exclusions, types


def _bar(items: Sequence, desc: str, enabled: bool):
    if not enabled:
        return items
    from tqdm import tqdm

    return tqdm(items, desc=desc, unit="item", leave=False)


def merge_units(units: Sequence[Unit]) -> list[Unit]:
    """Concatenate units that share target type and source types (one model call per group).

    The result is for pooled errors and fits only: its ``t_s`` is not monotonic."""
    groups: dict[tuple, list[Unit]] = {}
    for u in units:
        if len(u):
            groups.setdefault((u.split, u.type, u.source_types), []).append(u)
    out = []
    for (split, vtype, stypes), us in groups.items():
        if len(us) == 1:
            out.append(us[0])
            continue
        cat = lambda key: np.concatenate([getattr(u, key) for u in us])  # noqa: E731
        out.append(Unit(
            flight="+".join(u.flight for u in us), split=split, name="+".join(u.name for u in us), type=vtype,
            t_s=cat("t_s"), velocity_mps=cat("velocity_mps"), height_above_ground_m=cat("height_above_ground_m"),
            thrust_z_N=cat("thrust_z_N"), source_types=stypes,
            source_offsets_m=tuple(np.concatenate([u.source_offsets_m[k] for u in us]) for k in range(len(stypes))),
            force_N=cat("force_N"), torque_Nm=cat("torque_Nm"),
        ))  # fmt: skip
    return out


def subsample(units: Sequence[Unit], max_samples: int) -> list[Unit]:
    """Uniform-stride subsample of ``units`` keeping at most ``max_samples`` samples in total,
    merged by :func:`merge_units`."""
    total = sum(len(u) for u in units)
    stride = max(1, int(np.ceil(total / max(max_samples, 1))))
    return merge_units([u.take(np.arange(0, len(u), stride)) for u in units if len(u)])


# ------------------------------------------------------------------------------ errors


@dataclass(frozen=True)
class Errors:
    rmse_fz_N: float
    rmse_torque_Nm: float  # RMS of the torque error vector norm
    rmse_tz_Nm: float  # yaw torque
    n_samples: int

    def to_json(self) -> dict[str, float]:
        return {"rmse_fz_N": self.rmse_fz_N, "rmse_torque_Nm": self.rmse_torque_Nm, "rmse_tz_Nm": self.rmse_tz_Nm, "n_samples": self.n_samples}


def errors(units: Sequence[Unit], model: Model, *, bases: Sequence | None = None) -> Errors:
    """RMSEs of ``model`` on ``units``; ``bases`` optionally holds each unit's precomputed base wrench."""
    df, dt = [], []
    for k, u in enumerate(units):
        f, t = predict(u, model, base=None if bases is None else bases[k])
        df.append(u.force_N[:, 2] - f[:, 2])
        dt.append(u.torque_Nm - t)
    df_a, dt_a = np.concatenate(df), np.concatenate(dt)
    return Errors(
        rmse_fz_N=float(np.sqrt(np.mean(df_a**2))),
        rmse_torque_Nm=float(np.sqrt(np.mean(np.sum(dt_a**2, axis=1)))),
        rmse_tz_Nm=float(np.sqrt(np.mean(dt_a[:, 2] ** 2))),
        n_samples=int(df_a.size),
    )


# ------------------------------------------------------------------------------ calibration


def _roles(units: Sequence[Unit]) -> tuple[set[str], set[str], list[str]]:
    sources = {t for u in units for t in u.source_types}
    targets = {u.type for u in units if u.source_types}
    types = sorted({u.type for u in units})
    return sources, targets, types


def calibrate_model(units: Sequence[Unit], model: Model, *, options: IdentifyOptions) -> tuple[Model, CalibrationResult]:
    """Fit c_ax, z0_m, c_rad (source types), b_v (target types), thrust scale (all types) on F_z."""
    fit_units = subsample(units, options.max_fit_samples)
    sources, targets, types = _roles(fit_units)
    specs: list[ParamSpec] = []
    for t in types:
        specs += vehicle_param_specs(model.vehicles[t], f"{t}.", as_source=t in sources, as_target=t in targets)
        specs.append(ParamSpec(f"{t}.thrust_scale", model.thrust_scale.get(t, 1.0), 0.7, 1.3))
    y = np.concatenate([u.force_N[:, 2] for u in fit_units])

    def model_of(theta: np.ndarray) -> Model:
        per_type: dict[str, dict[str, float]] = {}
        for spec, val in zip(specs, theta):
            t, key = spec.name.rsplit(".", 1)
            per_type.setdefault(t, {})[key] = float(val)
        vehicles = dict(model.vehicles)
        scales = dict(model.thrust_scale)
        for t, vals in per_type.items():
            scales[t] = vals.pop("thrust_scale", 1.0)
            vehicles[t] = apply_vehicle_parameters(model.vehicles[t], **vals)
        return replace(model, vehicles=vehicles, thrust_scale=scales)

    def residual(theta: np.ndarray) -> np.ndarray:
        m = model_of(theta)
        return np.concatenate([predict(u, m)[0][:, 2] for u in fit_units]) - y

    result = fit_parameters(residual, specs, max_nfev=60 + 10 * len(specs))
    # the thrust scales were nuisance parameters (so a thrust-calibration error does not distort the
    # aerodynamic ones); whether to keep a thrust correction is decided by test error (thrust_bias)
    calibrated = model_of(result.values)
    return replace(calibrated, thrust_scale=dict(model.thrust_scale)), result


# ------------------------------------------------------------------------------ effects


@dataclass(frozen=True)
class EffectTrial:
    name: str
    params: dict[str, float]
    round: int
    test: Errors
    gain_fz: float  # relative cut of test F_z RMSE vs the model before this trial, -
    gain_tz: float  # same for yaw torque, -
    selected: bool = False

    def to_json(self) -> dict[str, Any]:
        return {"name": self.name, "params": self.params, "rmse_fz_N": self.test.rmse_fz_N,
                "rmse_torque_Nm": self.test.rmse_torque_Nm, "rmse_tz_Nm": self.test.rmse_tz_Nm,
                "gain_fz": self.gain_fz, "gain_tz": self.gain_tz, "round": self.round, "selected": self.selected}  # fmt: skip


def _initial_params(name: str, fit_units: Sequence[Unit], model: Model) -> dict[str, float]:
    """Start values: PARAMETERS defaults; own_velocity from the LS fit of the F_z residual (S1-25 form)."""
    p0 = {k: spec[0] for k, spec in PARAMETERS[name].items()}
    if name == "own_velocity":
        from costmaps.thrust_rls import fit_ls

        rows, ys = [], []
        for u in fit_units:
            w = model.vehicles[u.type].weight_N
            v = u.velocity_mps
            vxy = np.hypot(v[:, 0], v[:, 1])
            rows.append(np.column_stack([-v[:, 2], vxy, vxy**2, np.ones(len(u))]))
            ys.append((u.force_N[:, 2] - predict(u, model)[0][:, 2]) / w)
        fit = fit_ls(np.concatenate(rows), np.concatenate(ys))
        for key, val in zip(("c_w_spm", "c_mu_spm", "c_mu2_s2pm2"), fit.theta[:3]):
            lo, hi = PARAMETERS[name][key][1:]
            p0[key] = float(np.clip(val, lo, hi))
    return p0


_START_GRID: dict[str, list[dict[str, float]]] = {
    "wake_advection": [{"wind_x_mps": wx, "wind_y_mps": wy} for wx in (-2.0, -1.0, 0.0, 1.0, 2.0) for wy in (-2.0, -1.0, 0.0, 1.0, 2.0)],
    "near_field": [{"decay_L": d, "amplitude": a} for d in (1.0, 3.0, 10.0) for a in (0.3, 1.0, 3.0)],
    "ground_effect": [{"gain_k": k} for k in (0.5, 2.0, 3.5)],
}
"""Extra start points per effect (parameters not named keep their defaults)."""


def fit_effect(name: str, units: Sequence[Unit], model: Model, *, options: IdentifyOptions) -> tuple[Effect, Model]:
    """Fit one candidate effect (and the thrust scales) on train ``units``; returns it and the model with it."""
    fit_units = subsample(units, options.max_effect_fit_samples)
    bases = [base_wrench(unit_inputs(u, model)) for u in fit_units]  # vehicles frozen: reuse base
    p0 = _initial_params(name, fit_units, model)
    keys = list(PARAMETERS[name])
    # thrust_bias stands for the thrust-calibration error: a global bias plus per-type thrust scales
    types = sorted({u.type for u in fit_units}) if name == "thrust_bias" else []
    specs = [ParamSpec(k, p0[k], *PARAMETERS[name][k][1:]) for k in keys]
    specs += [ParamSpec(f"{t}.thrust_scale", model.thrust_scale.get(t, 1.0), 0.7, 1.3) for t in types]
    fz = np.concatenate([u.force_N[:, 2] for u in fit_units])
    tz = np.concatenate([u.torque_Nm[:, 2] for u in fit_units])
    f0 = np.concatenate([predict(u, model, base=b)[0][:, 2] for u, b in zip(fit_units, bases)])
    t0 = np.concatenate([predict(u, model, base=b)[1][:, 2] for u, b in zip(fit_units, bases)])
    s_f = max(float(np.sqrt(np.mean((fz - f0) ** 2))), 1e-9)  # normalise both channels to the
    s_t = max(float(np.sqrt(np.mean((tz - t0) ** 2))), 1e-12)  # current residual RMS, -

    def model_of(theta: np.ndarray) -> Model:
        eff = Effect(name, {k: float(v) for k, v in zip(keys, theta[: len(keys)])})
        scales = dict(model.thrust_scale) | {t: float(v) for t, v in zip(types, theta[len(keys):])}
        return replace(model, effects=model.effects + (eff,), thrust_scale=scales)

    def residual(theta: np.ndarray) -> np.ndarray:
        m = model_of(theta)
        preds = [predict(u, m, base=b) for u, b in zip(fit_units, bases)]
        pf = np.concatenate([p[0][:, 2] for p in preds])
        pt = np.concatenate([p[1][:, 2] for p in preds])
        return np.concatenate([(pf - fz) / s_f, (pt - tz) / s_t])

    # nonlinear effects can start far from their optimum: begin from the best point of a small grid
    starts = [np.array([s.initial for s in specs])]
    for extra in _START_GRID.get(name, ()):
        x0 = starts[0].copy()
        for k, v in extra.items():
            x0[keys.index(k)] = v
        starts.append(x0)
    if len(starts) > 1:
        best = min(starts, key=lambda x: float(np.sum(residual(x) ** 2)))
        specs = [replace(s, initial=float(v)) for s, v in zip(specs, best)]
    result = fit_parameters(residual, specs, max_nfev=40 + 10 * len(specs))
    m = model_of(result.values)
    return m.effects[-1], m


def _gain(new: float, current: float, floor: float) -> float:
    """Relative cut of an RMSE; 0 when the current one is below the noise ``floor``."""
    return 0.0 if current < floor else 1.0 - new / current


def select_effects(
    train: Sequence[Unit], test: Sequence[Unit], starts: Sequence[Model], *, options: IdentifyOptions
) -> tuple[Model, list[EffectTrial]]:
    """Greedy effect selection by TEST error (see the module docstring).

    ``starts`` are the models the first round builds on (the calibrated one and the model as given:
    calibration alone may bend the vehicle parameters towards a missing effect, after which the
    effect no longer fits); each candidate keeps the start that gives it the lower test error. The
    baseline of the gains is the better start.
    """
    test_eval = subsample(test, options.max_eval_samples)
    cache: dict[int, tuple[Any, list]] = {}  # id(vehicles) -> (vehicles, base wrench per test unit)

    def test_errors(m: Model) -> Errors:
        key = id(m.vehicles)
        if key not in cache:  # effect fits keep the vehicles: one base evaluation per start model
            cache[key] = (m.vehicles, [base_wrench(unit_inputs(u, m)) for u in test_eval])
        return errors(test_eval, m, bases=cache[key][1])

    scored = [(test_errors(m), m) for m in starts]
    current, model = min(scored, key=lambda em: em[0].rmse_fz_N / max(scored[0][0].rmse_fz_N, 1e-12)
                         + em[0].rmse_tz_Nm / max(scored[0][0].rmse_tz_Nm, 1e-15))  # fmt: skip
    trials: list[EffectTrial] = []
    remaining = [n for n in options.effects]
    rnd = 0
    while remaining and len(model.effects) < options.max_effects:
        rnd += 1
        bases = [m for _, m in scored] if rnd == 1 else [model]
        round_trials = []
        for name in _bar(remaining, f"effects round {rnd}", options.progress):
            best_here = None
            for base in bases:
                eff, cand = fit_effect(name, train, base, options=options)
                err = test_errors(cand)
                gf = _gain(err.rmse_fz_N, current.rmse_fz_N, 1e-6)
                gt = _gain(err.rmse_tz_Nm, current.rmse_tz_Nm, 1e-7)
                if best_here is None or gf + gt > best_here[0].gain_fz + best_here[0].gain_tz:
                    best_here = (EffectTrial(name, eff.full_params(), rnd, err, gf, gt), cand)
            round_trials.append(best_here)
        ok = [(t, c) for t, c in round_trials if max(t.gain_fz, t.gain_tz) >= options.min_gain and min(t.gain_fz, t.gain_tz) > -0.01]
        best = max(ok, key=lambda tc: tc[0].gain_fz + tc[0].gain_tz, default=None)
        for t, _ in round_trials:
            trials.append(replace(t, selected=best is not None and t is best[0]))
        if best is None:
            break
        model, current = best[1], best[0].test
        remaining.remove(best[0].name)
    return model, trials


# ------------------------------------------------------------------------------ pipeline


@dataclass(frozen=True)
class IdentifyResult:
    before: Errors
    after: Errors
    calibrated: Errors  # calibrated, no effects
    trials: list[EffectTrial]
    selected: list[str]
    base_model: Model
    final_model: Model
    calibration: CalibrationResult | None
    exclusions: dict
    correlations: list  # FeatureCorrelation of the final test F_z residual, strongest first
    correlations_before: list
    unexplained: dict | None
    validity: dict
    thrust_coefficient: dict
    units: list[Unit]

    def to_json(self) -> dict[str, Any]:
        cal = {}
        if self.calibration is not None:
            cal = {"parameters": self.calibration.to_json(), "rmse_fz_N_train": self.calibration.rmse, "success": self.calibration.success}
        return {
            "before": self.before.to_json(),
            "after": self.after.to_json(),
            "calibrated_only": self.calibrated.to_json(),
            "effects": [t.to_json() for t in self.trials],
            "selected": list(self.selected),
            "calibration": cal,
            "thrust_scale": dict(self.final_model.thrust_scale),
            "exclusions": self.exclusions,
            "residual_correlations": [{"feature": c.feature, "pearson": c.pearson, "eta": c.eta} for c in self.correlations],
            "unexplained": self.unexplained,
            "validity": self.validity,
            "thrust_coefficient": {t: {k: v for k, v in d.items() if not k.startswith("_")} for t, d in self.thrust_coefficient.items()},
        }


def _zone_masks(u: Unit, model: Model) -> tuple[np.ndarray, np.ndarray]:
    """Per sample of ``u``: below some source within r < 3 L (N,), and of those, in dz > 3 L (N,)."""
    below = np.zeros(len(u), dtype=bool)
    valid = np.zeros(len(u), dtype=bool)
    for t, off in zip(u.source_types, u.source_offsets_m):
        L = model.vehicles[t].size_m
        dz, r = -off[:, 2], np.hypot(off[:, 0], off[:, 1])
        here = (dz > 0.0) & (r < 3.0 * L)
        below |= here
        valid |= here & (dz > VALIDITY_FACTOR_L * L)
    return below, valid


def _validity(units: Sequence[Unit], before: Model, after: Model, bases_before: list, bases_after: list) -> dict[str, Any]:
    """Samples below a source (dz > 0, r < 3 L) inside / outside the zone dz > 3 L (S0 II-A), with
    the test RMSE of F_z before and after on each part."""
    below, valid, res_b, res_a = [], [], [], []
    for u, bb, ba in zip(units, bases_before, bases_after):
        b, v = _zone_masks(u, before)
        below.append(b)
        valid.append(v)
        res_b.append(u.force_N[:, 2] - predict(u, before, base=bb)[0][:, 2])
        res_a.append(u.force_N[:, 2] - predict(u, after, base=ba)[0][:, 2])
    below_a, valid_a = np.concatenate(below), np.concatenate(valid)
    rb, ra = np.concatenate(res_b), np.concatenate(res_a)

    def rmse(r: np.ndarray, m: np.ndarray) -> float | None:
        return float(np.sqrt(np.mean(r[m] ** 2))) if m.any() else None

    inside, outside = below_a & valid_a, below_a & ~valid_a
    return {
        "samples_below_a_source": int(below_a.sum()),
        "samples_in_valid_zone": int(inside.sum()),
        "fraction_valid": float(inside.sum() / below_a.sum()) if below_a.any() else None,
        "rmse_fz_N_valid_zone": {"before": rmse(rb, inside), "after": rmse(ra, inside)},
        "rmse_fz_N_inside_3L": {"before": rmse(rb, outside), "after": rmse(ra, outside)},
        "note": "model valid for dz > 3 L of the source (S0 II-A); closer samples are still compared",
    }


def _residual_analysis(units: Sequence[Unit], model: Model):
    res, feats = [], {}
    for u in units:
        f, _ = predict(u, model)
        res.append(u.force_N[:, 2] - f[:, 2])
        fe = sample_features(u.height_above_ground_m, u.velocity_mps, list(u.source_offsets_m))
        for k, v in fe.items():
            feats.setdefault(k, []).append(v)
    return correlate(np.concatenate(res), {k: np.concatenate(v) for k, v in feats.items()})


def run_identify(manifest: Manifest | str | Path, *, options: IdentifyOptions = IdentifyOptions(), thrust_summary: bool = True) -> IdentifyResult:
    """The whole pipeline on a manifest; errors are on TEST flights."""
    if not isinstance(manifest, Manifest):
        manifest = load_manifest(manifest)
    units, exclusions, types = load_units(manifest, options=options)
    train = [u for u in units if u.split == "train" and len(u)]
    test = [u for u in units if u.split == "test" and len(u)]
    if not train or not test:
        raise UserError(f"{manifest.path}: after quality checks there must be samples on train and test flights")
    base = Model(vehicles=types, thrust_scale={t: 1.0 for t in types}, options=ModelOptions(field_form=options.field_form))
    test_all = merge_units(test)  # every test sample, pooled
    cache: dict[int, tuple[Any, list]] = {}  # id(vehicles) -> (vehicles, base wrench per unit)

    def full_bases(m: Model) -> list:
        key = id(m.vehicles)
        if key not in cache:
            cache[key] = (m.vehicles, [base_wrench(unit_inputs(u, m)) for u in test_all])
        return cache[key][1]

    def full_errors(m: Model) -> Errors:
        return errors(test_all, m, bases=full_bases(m))

    before = full_errors(base)
    calibration = None
    model = base
    if options.calibrate:
        model, calibration = calibrate_model(train, base, options=options)
    calibrated = full_errors(model)
    corr_before = _residual_analysis(subsample(train, 20000), model)
    final, trials = select_effects(train, test, [model, base] if options.calibrate else [base], options=options)
    after = full_errors(final)
    corr = _residual_analysis(subsample(test, 50000), final)
    unexplained = None
    if corr and corr[0].strength >= 0.3:
        unexplained = {"feature": corr[0].feature, "pearson": corr[0].pearson, "eta": corr[0].eta,
                       "note": "the residual after the kept effects still follows this feature; no effect in the library explained it"}  # fmt: skip
    thrust = thrust_coefficient_summary(train) if thrust_summary else {}
    return IdentifyResult(
        before=before, after=after, calibrated=calibrated, trials=trials,
        selected=[e.name for e in final.effects], base_model=base, final_model=final,
        calibration=calibration, exclusions=exclusions, correlations=corr, correlations_before=corr_before,
        unexplained=unexplained, validity=_validity(test_all, base, final, full_bases(base), full_bases(final)), thrust_coefficient=thrust, units=units,
    )  # fmt: skip


def thrust_coefficient_summary(units: Sequence[Unit]) -> dict:
    """Seed 001 on the given (train) units: LS fit of (S1-25) per vehicle type and a decimated RLS
    history (S1-28..S1-30, forgetting factor 0.99, started from the LS solution as the paper does)."""
    from costmaps.thrust_rls import REGRESSOR_NAMES, fit_ls, rls

    out: dict[str, Any] = {}
    for t in sorted({u.type for u in units if u.thrust is not None}):
        samples = [u.thrust for u in units if u.type == t and u.thrust is not None]
        x = np.concatenate([s.regressors for s in samples])
        y = np.concatenate([s.c_t for s in samples])
        fit = fit_ls(x, y)
        step = max(1, len(y) // 2000)
        hist = rls(x[::step], y[::step], forgetting=0.99, theta0=fit.theta)
        out[t] = {
            "ls": {n: float(v) for n, v in zip(REGRESSOR_NAMES, fit.theta)},
            "ls_std": {n: float(v) for n, v in zip(REGRESSOR_NAMES, fit.std)},
            "r2": fit.r2,
            "n_samples": int(len(y)),
            "rls_final": {n: float(v) for n, v in zip(REGRESSOR_NAMES, hist[-1])},
            "_rls_history": hist,  # (M, 6) for the report plot; not in the JSON
        }
    return out
