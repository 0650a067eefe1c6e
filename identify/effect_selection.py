"""Candidate effects of the identification pipeline: fit on train flights, select by TEST error.

Stage 5 of :mod:`identify.pipeline`: each candidate of :data:`physics.effects.EFFECT_NAMES` is
fitted on train flights on top of the calibrated model and scored on test flights; the greedy
selection keeps what lowers the test error.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from identify.calibrate import ParamSpec, fit_parameters
from identify.data import Errors, IdentifyOptions, Model, Unit, errors, predict, progress_bar, subsample, unit_inputs
from physics import PARAMETERS, Effect, base_wrench

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
        from identify.thrust_rls import fit_ls

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
        for name in progress_bar(remaining, f"effects round {rnd}", options.progress):
            best_here = None
            for base in bases:
                eff, cand = fit_effect(name, train, base, options=options)
                err = test_errors(cand)
                gf = _gain(err.rmse_fz_N, current.rmse_fz_N, 1e-6)
                gt = _gain(err.rmse_tz_Nm, current.rmse_tz_Nm, 1e-7)
                if best_here is None or gf + gt > best_here[0].gain_fz + best_here[0].gain_tz:
                    best_here = (EffectTrial(name, eff.full_params(), rnd, err, gf, gt), cand)
            assert best_here is not None  # at least one candidate per round
            round_trials.append(best_here)
        ok = [
            (t, c)
            for t, c in round_trials
            if max(t.gain_fz, t.gain_tz) >= options.min_gain and min(t.gain_fz, t.gain_tz) > -0.01
        ]
        best = max(ok, key=lambda tc: tc[0].gain_fz + tc[0].gain_tz, default=None)
        for t, _ in round_trials:
            trials.append(replace(t, selected=best is not None and t is best[0]))
        if best is None:
            break
        model, current = best[1], best[0].test
        remaining.remove(best[0].name)
    return model, trials
