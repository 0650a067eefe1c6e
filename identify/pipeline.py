"""``proxplan identify`` pipeline: measure -> predict -> calibrate -> select -> discover -> report.

Stages (DESIGN.md section 6; issue 35):

1. Load every flight of the manifest (:mod:`proxplan.identify.flightlog`), clean it and measure the disturbance
   on every vehicle (:mod:`proxplan.identify.measure`, S0-11, S0-13 + gyroscopic term) with the motor thrust
   each motor DELIVERS: from PWM and Vbat through a per-type thrust map fitted on train flights,
   capped where a motor saturates (:mod:`proxplan.identify.thrust_map`).
2. Predict it with the model: :func:`proxplan.physics.effects.total_wrench`, i.e. the base model
   (:func:`proxplan.physics.disturbance.disturbance_wrench`) summed over all other vehicles of the flight at
   their logged relative positions (interpolated onto the target's own clock), plus effects.
3. Calibrate on the train flights (:mod:`proxplan.identify.calibrate`), MAP: per source type c_ax, z0_m,
   c_rad; per target type b_v; each with its prior (:mod:`proxplan.identify.priors`), the data term in
   units of the F_z noise per independent sample (the residual's integrated autocorrelation time); a
   per-type thrust scale is fitted jointly as a nuisance parameter and then dropped (``thrust_bias``
   may earn it back). The report says how far each parameter moved in prior sigmas and whether the data
   informed it.
4. Residual analysis (:mod:`proxplan.identify.residuals`).
5. Effects (:mod:`proxplan.identify.effect_selection`) and 6. discovered terms
   (:mod:`proxplan.identify.discovery`), both judged by flights held out
   (:mod:`proxplan.identify.crossval`): the vehicle parameters are refitted jointly with every candidate
   (their tangent columns, with their priors), a candidate is kept only when its held-out gain exceeds
   the Bonferroni multiple of the flight-to-flight standard error AND it is chosen in most half-samples
   of the flights. The calibration may have absorbed a missing effect into the vehicle parameters, so
   selection also runs around the PRIOR model, and the start whose kept set predicts the held-out flights
   better is kept (:func:`proxplan.identify.selection.other_start_better`).
7. Errors before (model as given), calibrated and after (calibrated + kept effects) on TEST flights,
   which never choose anything; also per vehicle (the manifest's key).

Vehicles marked ``score: false`` in the manifest are downwash sources only (never fitted or scored).
Fits use stratified samples (``max_fit_samples``; :mod:`proxplan.identify.strata`); the before/after
figures use every test sample.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from proxplan.fanout import Background, background
from proxplan.fileio import UserError
from proxplan.identify.calibrate import (
    STACK_PARAMETER,
    CalibrationResult,
    calibrate_model,
    model_specs,
)
from proxplan.identify.command_check import measured_with_holds
from proxplan.identify.data import (
    Errors,
    IdentifyOptions,
    Model,
    Predictions,
    Unit,
    errors,
    predict,
    rmse_fz_by_vehicle,
    subsample,
)
from proxplan.identify.effect_selection import EffectTrial
from proxplan.identify.evaluate import GRAMS_PER_N, saved_model
from proxplan.identify.flightlog import Manifest
from proxplan.identify.loading import load_units, measurement_summary
from proxplan.identify.manifest import load_manifest
from proxplan.identify.measure import MeasureOptions
from proxplan.identify.motor_check import check_loaded
from proxplan.identify.noise import noise_level
from proxplan.identify.priors import STACK_SHIELDING_PRIOR
from proxplan.identify.residuals import correlate, sample_features
from proxplan.identify.selection import other_start_better, select_and_discover
from proxplan.identify.spread import band_errors, fit_spread
from proxplan.physics import (
    VALIDITY_FACTOR_L,
    CalibratedModel,
    ModelOptions,
    ResidualSpread,
    one_blas_thread,
)

# ------------------------------------------------------------------------------ pipeline


PARALLEL_STAGES = 2
"""Stages of :func:`run_identify` that can run at once, -: the pipeline has two independent branches at
most (the motor-lag check beside the calibration, then the two starts of the selection), so a worker
beyond one process beside the caller would idle."""


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
    thrust_maps: dict = field(default_factory=dict)  # vehicle type -> proxplan.identify.thrust_map.ThrustMap
    notes: list[str] = field(default_factory=list)
    measure_options: MeasureOptions = MeasureOptions()
    per_vehicle: dict = field(default_factory=dict)  # NAME -> rmse_fz_N_before/calibrated/after, n_samples (test)
    discovered: list = field(default_factory=list)  # data-driven terms (proxplan.identify.discovery); [] when none
    calibrated_model: Model | None = None  # calibrated, no effects (what "calibrated_only" scored)
    validation: str = ""  # how the flights were held out (proxplan.identify.crossval.plan_groups), fallback said
    stack_shielding: dict | None = None  # eta of the stacks (proxplan.physics.stack): calibrated with its prior
    motor_lag_check: dict = field(default_factory=dict)  # proxplan.identify.motor_check (warnings inside)
    command_hold: dict = field(default_factory=dict)  # type -> proxplan.identify.command_check.CommandHold
    selection: dict = field(default_factory=dict)  # Selection.to_json of the start that won (+ the other's total)
    fallback: bool = False  # selection fell back to blocks in time (too few flights)
    spread: ResidualSpread | None = None  # what the final model cannot predict (proxplan.identify.spread)
    bands: dict = field(default_factory=dict)  # test set -> F_z RMSE below / above 1 Hz, 90 % coverage
    timings: dict = field(default_factory=dict)  # stage -> wall time, s

    def saved(self) -> CalibratedModel:
        """The model file's content: everything the "after" figure used, and the residual spread."""
        return saved_model(self.final_model, self.measure_options, self.thrust_maps, self.spread)

    def _unkept_tests(self) -> list[tuple[str, dict[str, Any]]]:
        tests = [(t.name, t.gain_last.to_json()) for t in self.trials if not t.selected and t.gain_last is not None]
        tests += [(f"{d['channel']}*{d['feature']}", d["heldout_gain"]) for d in self.discovered
                  if not d.get("selected") and d.get("heldout_gain")]  # fmt: skip
        return tests

    def undecided(self) -> list[str]:
        """One line per effect or discovered term not kept although every held-out flight gained from it
        (:attr:`proxplan.identify.heldout_select.GainTest.undecided`): the flights were too few to decide."""
        return [_undecided_line(name, g) for name, g in self._unkept_tests() if g["undecided"]]

    def one_flight(self) -> list[str]:
        """One line per effect or discovered term not kept whose held-out change lies mostly on one flight
        (:attr:`proxplan.identify.heldout_select.GainTest.one_flight`): these flights cannot test it."""
        return [_one_flight_line(name, g) for name, g in self._unkept_tests() if g.get("one_flight")]

    def measurement_json(self) -> dict[str, Any]:
        """Thrust maps, notes and per-vehicle saturation counts (pooled over every flight)."""
        return measurement_summary(self.thrust_maps, self.exclusions, self.notes)

    def to_json(self) -> dict[str, Any]:
        cal = {}
        if self.calibration is not None:
            cal = {
                "parameters": self.calibration.to_json(),
                "priors": self.calibration.prior_report(),
                "large_moves": self.calibration.large_moves(),
                "rmse_fz_N_train": self.calibration.rmse,
                "success": self.calibration.success,
            }
        return {
            "before": self.before.to_json(),
            "after": self.after.to_json(),
            "calibrated_only": self.calibrated.to_json(),
            "effects": [t.to_json() for t in self.trials],
            "selected": list(self.selected),
            "calibration": cal,
            "thrust_scale": dict(self.final_model.thrust_scale),
            "exclusions": self.exclusions,
            "measurement": self.measurement_json(),
            "per_vehicle": self.per_vehicle,
            "discovered": list(self.discovered),
            "validation": self.validation,
            "selection_fallback": self.validation if self.fallback else None,
            "selection": self.selection,
            "residual_spread": None if self.spread is None else self.spread.to_dict(),
            "test_bands": self.bands,
            "timings_s": self.timings,
            "stack_shielding": self.stack_shielding,
            "motor_lag_check": self.motor_lag_check,
            "command_hold": {t: h.to_dict() for t, h in self.command_hold.items()},
            "warnings": list(self.motor_lag_check.get("warnings", [])),
            "undecided": self.undecided(),
            "one_flight": self.one_flight(),
            "residual_correlations": [
                {"feature": c.feature, "pearson": c.pearson, "eta": c.eta} for c in self.correlations
            ],
            "unexplained": self.unexplained,
            "validity": self.validity,
            "thrust_coefficient": {
                t: {k: v for k, v in d.items() if not k.startswith("_")} for t, d in self.thrust_coefficient.items()
            },
        }


def _undecided_line(name: str, gain: dict[str, Any]) -> str:
    n, t = gain["n_groups"], gain["t"]
    shown = "inf" if t is None else f"{t:.2f}"
    return (f"{name}: every one of the {n} held-out flights gained (t = {shown}), but over {n} flights the test "
            f"needs t > {gain['z_required']:.2f}: not kept; more train flights would decide it")  # fmt: skip


def _one_flight_line(name: str, gain: dict[str, Any]) -> str:
    if gain["n_groups"] == 1:
        where = f"it acts on one held-out flight only (held-out gain there {gain['mean_gain']:+.3g})"
    else:
        where = (f"what it changes on the held-out flights lies mostly on one of them (Kish's effective number of "
                 f"flights {gain['effective_flights']:.2f} of {gain['n_groups']}, under two; held-out gain "
                 f"{gain['mean_gain']:+.3g})")  # fmt: skip
    return (f"{name}: {where}: less than two flights' worth of evidence, the test of flights held out cannot judge "
            "it either way; fly that situation in more flights")  # fmt: skip


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


def _validity(units: Sequence[Unit], before: Model, after: Model, pred: Predictions) -> dict[str, Any]:
    """Samples below a source (dz > 0, r < 3 L) inside / outside the zone dz > 3 L (S0 II-A), with
    the test RMSE of F_z before and after on each part."""
    below, valid, res_b, res_a = [], [], [], []
    for u in units:
        b, v = _zone_masks(u, before)
        below.append(b)
        valid.append(v)
        res_b.append(u.force_N[:, 2] - pred(u, before)[0][:, 2])
        res_a.append(u.force_N[:, 2] - pred(u, after)[0][:, 2])
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


def _residual_analysis(units: Sequence[Unit], model: Model, pred: Predictions | None = None):
    res: list[np.ndarray] = []
    feats: dict[str, list[np.ndarray]] = {}
    for u in units:
        f, _ = pred(u, model) if pred is not None else predict(u, model)
        res.append(u.force_N[:, 2] - f[:, 2])
        fe = sample_features(u.height_above_ground_m, u.velocity_mps, list(u.source_offsets_m))
        for k, v in fe.items():
            feats.setdefault(k, []).append(v)
    return correlate(np.concatenate(res), {k: np.concatenate(v) for k, v in feats.items()})


def _per_vehicle(
    test: Sequence[Unit], before: Model, calibrated: Model, after: Model, pred: Predictions
) -> dict[str, dict]:
    """Test RMSE of F_z per vehicle name, before / calibrated / after (pooled over test flights)."""
    b, c, a = (rmse_fz_by_vehicle(test, m, pred) for m in (before, calibrated, after))
    return {k: {"rmse_fz_N_before": b[k][0], "rmse_fz_N_calibrated": c[k][0], "rmse_fz_N_after": a[k][0],
                "n_samples": b[k][1]} for k in b}  # fmt: skip


@one_blas_thread
def run_identify(
    manifest: Manifest | str | Path, *, options: IdentifyOptions | None = None, thrust_summary: bool = True
) -> IdentifyResult:
    """The whole pipeline on a manifest; errors are on TEST flights. With ``options.workers`` > 1 the
    motor-lag check runs beside the calibration and the selection around the prior model beside the one
    around the calibrated model, in a worker process (:func:`proxplan.fanout.background`); the result is
    the same as with 1 (every stage depends on its arguments only)."""
    options = options or IdentifyOptions()
    if not isinstance(manifest, Manifest):
        manifest = load_manifest(manifest)
    with background(min(options.workers, PARALLEL_STAGES) - 1) as side:
        return _run(manifest, options, side, thrust_summary)


def _run(manifest: Manifest, options: IdentifyOptions, side: Background, thrust_summary: bool) -> IdentifyResult:
    """:func:`run_identify` with the stages that may run beside the caller submitted to ``side``."""
    laps = _Laps()
    data = load_units(manifest, options=options)
    laps("load and measure")
    options, data, holds = measured_with_holds(manifest, options, data)  # identify.command_check
    laps("command hold check (and measured again where a type is not held)")
    units, exclusions, types = data.units, data.exclusions, data.types
    lag_task = side.submit("the motor lag check", check_loaded, side.share(data), motor_thrust=manifest.motor_thrust,
                           options=options.measure)  # fmt: skip
    fit = [u for u in units if u.split == "train" and u.scored and len(u)]
    test = [u for u in units if u.split == "test" and u.scored and len(u)]
    valid = [u for u in units if u.split == "validation" and u.scored and len(u)]
    if not fit or not test:
        raise UserError(f"{manifest.path}: after quality checks there must be samples on train and test flights")
    base = Model(  # "before": S0 as published, sources' wrenches summed pair by pair (no stack shielding)
        vehicles=types,
        thrust_scale={t: 1.0 for t in types},
        options=ModelOptions(field_form=options.field_form, stack_shielding=0.0),
    )
    pred = Predictions()  # every test sample scored many ways: each model's base wrench once per test log

    def full_errors(m: Model) -> Errors:
        return errors(test, m, predictions=pred)

    before = full_errors(base)
    noise = noise_level(fit, base)
    calibration = None
    fitted = None  # the calibration's own fit, with its thrust scales
    model = base
    # the calibration's priors: eta (proxplan.physics.stack) is calibrated with the rest where the data hold stacks
    prior_start = replace(base, options=replace(base.options, stack_shielding=options.stack_shielding))
    if options.calibrate:
        model, calibration, fitted = calibrate_model(fit, prior_start, options=options, noise=noise)
        noise = noise_level(fit, fitted)  # the selection weighs by the noise left around the calibrated model
    test_eval = subsample(test, options.max_eval_samples)
    alt_task = None
    if calibration is not None:
        # the calibration may have absorbed a missing effect into the vehicle parameters (their tangents
        # undo it only to first order), so selection also starts from the PRIOR model (eta at its prior);
        # it wins when its kept set predicts the held-out flights better (selection.other_start_better;
        # same samples, same units), else the calibrated start stays
        prior = replace(base, options=replace(base.options, stack_shielding=STACK_SHIELDING_PRIOR.center))
        quiet = replace(options, progress=options.progress and side.workers == 0)  # one process draws the bars
        alt_task = side.submit("the selection around the prior model", select_and_discover, fit, valid, prior,
                               model_specs(fit, prior), options=quiet, noise=noise, test=test_eval, start="prior",
                               prior_model=prior_start)  # fmt: skip
    calibrated = full_errors(model)  # after the submission: the worker need not wait for these test errors
    laps("calibration")
    corr_before = _residual_analysis(subsample(fit, 20000), model)
    specs = model_specs(fit, model)
    chosen = select_and_discover(fit, valid, model, specs, options=options, noise=noise, test=test_eval,
                                 calibrated_thrust_scale=None if fitted is None else fitted.thrust_scale,
                                 prior_model=prior_start)  # fmt: skip
    laps("selection around the calibrated model")
    other_total = None
    if alt_task is not None:
        alt = alt_task.result()
        other_total = alt.heldout_total
        if other_start_better(chosen, alt):
            chosen, other_total = alt, chosen.heldout_total
        laps.stage("selection around the prior model", alt_task.seconds)
    lag_check = lag_task.result()
    laps.stage("motor lag check", lag_task.seconds)
    laps("waiting for the stages beside")
    final = chosen.model
    after = full_errors(final)
    spread = fit_spread(chosen.rows, final, chosen.heldout_fz_N)  # set on flights the fit did not see
    bands = {k: b.to_json(GRAMS_PER_N)
             for k, b in band_errors(test, final, spread, test_sets(manifest, test), pred).items()}  # fmt: skip
    corr = _residual_analysis(test, final, pred)
    unexplained = None
    if corr and corr[0].strength >= 0.3:
        unexplained = {"feature": corr[0].feature, "pearson": corr[0].pearson, "eta": corr[0].eta,
                       "note": "the residual after the kept effects still follows this feature; no effect in the library explained it"}  # fmt: skip
    discovered = chosen.discovery.report() if chosen.discovery is not None else []
    for entry in discovered:
        if entry["selected"]:
            entry["rmse_fz_N"] = after.rmse_fz_N
    thrust = thrust_coefficient_summary(fit) if thrust_summary else {}
    selection = chosen.to_json() | {"other_start_heldout_mse": other_total}
    laps("spread, errors and analysis")
    return IdentifyResult(
        before=before, after=after, calibrated=calibrated, trials=chosen.effects.trials,
        selected=[e.name for e in final.effects], base_model=base, final_model=final,
        calibration=calibration, exclusions=exclusions, correlations=corr, correlations_before=corr_before,
        unexplained=unexplained, validity=_validity(test, base, final, pred),
        thrust_coefficient=thrust, units=units, thrust_maps=data.thrust_maps, notes=data.notes,
        measure_options=options.measure, per_vehicle=_per_vehicle(test, base, model, final, pred),
        validation=chosen.note, calibrated_model=model, discovered=discovered,
        stack_shielding=_stack_record(calibration, final), motor_lag_check=lag_check,
        command_hold=holds, selection=selection, fallback="fell back" in chosen.note, spread=spread, bands=bands, timings=laps.seconds,
    )  # fmt: skip


class _Laps:
    """Wall time of each stage, s (``identify.json["timings_s"]``): the caller's stages lap by lap; a stage
    run beside it (:func:`proxplan.fanout.background`) with its own wall time, so stages may overlap and
    ``"total"`` is the whole run's wall time."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = {}
        self._t0 = self._t = time.perf_counter()

    def __call__(self, stage: str) -> None:
        now = time.perf_counter()
        self.seconds[stage] = now - self._t
        self.seconds["total"] = now - self._t0
        self._t = now

    def stage(self, stage: str, seconds: float) -> None:
        """Record a stage that ran beside the caller, ``seconds`` (s) of its own."""
        self.seconds[stage] = seconds


def _stack_record(calibration: CalibrationResult | None, final: Model) -> dict | None:
    """The stack shielding eta: as calibrated (value, posterior std, prior report) and in the final model."""
    if calibration is None or STACK_PARAMETER not in calibration.names:
        return {"eta": final.options.stack_shielding, "note": "not calibrated: no stacks in the train flights"}
    k = calibration.names.index(STACK_PARAMETER)
    return {"eta": final.options.stack_shielding, "calibrated": float(calibration.values[k]),
            "std": float(calibration.std[k]) if np.isfinite(calibration.std[k]) else None,
            "prior": calibration.prior_report().get(STACK_PARAMETER)}  # fmt: skip


def test_sets(manifest: Manifest, units: Sequence[Unit]) -> dict[str, list[str]]:
    """The test flights by experiment set (the manifest's ``set``), plus ``all``."""
    flights = sorted({u.flight for u in units})
    set_of = {f.name: f.set for f in manifest.flights}
    out: dict[str, list[str]] = {"all": flights}
    for f in flights:
        out.setdefault(set_of.get(f, f), []).append(f)
    return out


def thrust_coefficient_summary(units: Sequence[Unit]) -> dict:
    """Seed 001 on the given (train) units: LS fit of (S1-25) per vehicle type and a decimated RLS
    history (S1-28..S1-30, forgetting factor 0.99, started from the LS solution as the paper does)."""
    from proxplan.identify.thrust_rls import REGRESSOR_NAMES, fit_ls, rls

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
