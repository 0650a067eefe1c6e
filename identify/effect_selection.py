"""Candidate effects of the identification pipeline: fit on train flights, select on VALIDATION flights.

Stage 5 of :mod:`proxplan.identify.pipeline`: each candidate of :data:`proxplan.physics.effects.EFFECT_NAMES` is
fitted on the fitting part of the train flights on top of the calibrated model and scored on the
validation part (flights carved from the train flights, :func:`validation_split`); the greedy
selection keeps what lowers the validation error. Test flights only report (each trial's test
error is in the JSON), they never choose.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from proxplan.identify.calibrate import ParamSpec, fit_parameters
from proxplan.identify.data import (
    Errors,
    IdentifyOptions,
    Model,
    Unit,
    errors,
    predict,
    progress_bar,
    subsample,
    unit_inputs,
)
from proxplan.physics import PARAMETERS, Effect, base_wrench

# ------------------------------------------------------------------------------ effects


@dataclass(frozen=True)
class EffectTrial:
    name: str
    params: dict[str, float]
    round: int
    test: Errors  # on the test flights (reported only)
    gain_fz: float  # relative cut of VALIDATION F_z RMSE vs the model before this trial, -
    gain_tz: float  # same for yaw torque, -
    selected: bool = False
    valid: Errors | None = None  # on the validation flights (what chose)

    def to_json(self) -> dict[str, Any]:
        return {"name": self.name, "params": self.params, "rmse_fz_N": self.test.rmse_fz_N,
                "rmse_torque_Nm": self.test.rmse_torque_Nm, "rmse_tz_Nm": self.test.rmse_tz_Nm,
                "rmse_fz_N_validation": None if self.valid is None else self.valid.rmse_fz_N,
                "gain_fz": self.gain_fz, "gain_tz": self.gain_tz, "round": self.round, "selected": self.selected}  # fmt: skip


def _initial_params(name: str, fit_units: Sequence[Unit], model: Model) -> dict[str, float]:
    """Start values: PARAMETERS defaults; own_velocity from the LS fit of the F_z residual (S1-25 form)."""
    p0 = {k: spec[0] for k, spec in PARAMETERS[name].items()}
    if name == "own_velocity":
        from proxplan.identify.thrust_rls import fit_ls

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
    "wake_advection": [
        {"wind_x_mps": wx, "wind_y_mps": wy} for wx in (-2.0, -1.0, 0.0, 1.0, 2.0) for wy in (-2.0, -1.0, 0.0, 1.0, 2.0)
    ],
    "near_field": [{"decay_L": d, "amplitude": a} for d in (1.0, 3.0, 10.0) for a in (0.3, 1.0, 3.0)],
    "ground_effect": [{"gain_k": k} for k in (0.5, 2.0, 3.5)],
    "ground_jet": [{"decay_L": d, "amplitude_1": a} for d in (1.0, 4.0, 10.0) for a in (0.2, 0.6)],
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
        scales = dict(model.thrust_scale) | {t: float(v) for t, v in zip(types, theta[len(keys) :])}
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


def validation_split(train: Sequence[Unit]) -> tuple[list[Unit], list[Unit], str]:
    """Split train units into (fit, validation) BY FLIGHT, and say how.

    Flights are grouped by name without a trailing ``_NN`` run number (e.g. ``swap_sl_03`` ->
    ``swap_sl``); in every group of two or more flights the last (in name order) validates. With no
    such group, the last train flight validates; with a single train flight, its last third (by
    time, per vehicle) validates — the only by-sample split, said in the note.
    """
    import re

    flights = sorted({u.flight for u in train})
    groups: dict[str, list[str]] = {}
    for f in flights:
        groups.setdefault(re.sub(r"_?\d+$", "", f), []).append(f)
    valid = {g[-1] for g in groups.values() if len(g) >= 2}
    if not valid and len(flights) >= 2:
        valid = {flights[-1]}
    if valid:
        fit = [u for u in train if u.flight not in valid]
        return fit, [u for u in train if u.flight in valid], f"validation flights: {', '.join(sorted(valid))}"
    fit, val = [], []
    for u in train:
        cut = int(len(u) * 2 / 3)
        fit.append(u.take(np.arange(cut)))
        val.append(u.take(np.arange(cut, len(u))))
    return fit, val, f"one train flight ({flights[0]}): its last third (by time) validates"


def select_effects(
    train: Sequence[Unit],
    valid: Sequence[Unit],
    starts: Sequence[Model],
    *,
    options: IdentifyOptions,
    test: Sequence[Unit] = (),
) -> tuple[Model, list[EffectTrial]]:
    """Greedy effect selection by VALIDATION error (see the module docstring).

    ``starts`` are the models the first round builds on (the calibrated one and the model as given:
    calibration alone may bend the vehicle parameters towards a missing effect, after which the
    effect no longer fits); each candidate keeps the start that gives it the lower validation
    error. The baseline of the gains is the better start. ``test`` units only get each trial's
    error reported.
    """
    valid_eval = subsample(valid, options.max_eval_samples)
    test_eval = subsample(test, options.max_eval_samples) if test else valid_eval
    cache: dict[tuple[int, int], tuple[Any, list]] = {}  # (id(vehicles), set) -> (vehicles, base wrenches)

    def set_errors(m: Model, units: list[Unit]) -> Errors:
        key = (id(m.vehicles), id(units))
        if key not in cache:  # effect fits keep the vehicles: one base evaluation per start model
            cache[key] = (m.vehicles, [base_wrench(unit_inputs(u, m)) for u in units])
        return errors(units, m, bases=cache[key][1])

    def valid_errors(m: Model) -> Errors:
        return set_errors(m, valid_eval)

    scored = [(valid_errors(m), m) for m in starts]
    current, model = min(scored, key=lambda em: em[0].rmse_fz_N / max(scored[0][0].rmse_fz_N, 1e-12)
                         + em[0].rmse_tz_Nm / max(scored[0][0].rmse_tz_Nm, 1e-15))  # fmt: skip
    trials: list[EffectTrial] = []
    # library names are fitted here; Effects (options.extra_candidates, e.g. data-driven terms
    # fitted elsewhere on the fitting flights) are scored with their parameters as given
    remaining: list[str | Effect] = [*options.effects, *options.extra_candidates]
    rnd = 0
    while remaining and len(model.effects) < options.max_effects:
        rnd += 1
        bases = [m for _, m in scored] if rnd == 1 else [model]
        round_trials = []
        for item in progress_bar(remaining, f"effects round {rnd}", options.progress):
            best_here = None
            for base in bases:
                if isinstance(item, Effect):
                    eff, cand = item, replace(base, effects=base.effects + (item,))
                else:
                    eff, cand = fit_effect(item, train, base, options=options)
                err = valid_errors(cand)
                gf = _gain(err.rmse_fz_N, current.rmse_fz_N, 1e-6)
                gt = _gain(err.rmse_tz_Nm, current.rmse_tz_Nm, 1e-7)
                if best_here is None or gf + gt > best_here[0].gain_fz + best_here[0].gain_tz:
                    best_here = (EffectTrial(eff.name, eff.full_params(), rnd, err, gf, gt, valid=err), cand, item)
            assert best_here is not None  # at least one candidate per round
            round_trials.append(best_here)
        ok = [
            (t, c, i)
            for t, c, i in round_trials
            if max(t.gain_fz, t.gain_tz) >= options.min_gain and min(t.gain_fz, t.gain_tz) > -0.01
        ]
        best = max(ok, key=lambda tci: tci[0].gain_fz + tci[0].gain_tz, default=None)
        for t, c, _ in round_trials:
            trials.append(replace(t, selected=best is not None and t is best[0], test=set_errors(c, test_eval)))
        if best is None:
            break
        model, current = best[1], best[0].valid or best[0].test
        remaining.remove(best[2])
    return model, trials
