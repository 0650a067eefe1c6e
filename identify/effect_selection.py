"""Candidate effects of the identification pipeline: fit on train flights, select on VALIDATION flights.

Stage 5 of :mod:`proxplan.identify.pipeline`: each candidate of :data:`proxplan.physics.effects.EFFECT_NAMES` is
fitted on the train flights (a stratified, weighted sample: :mod:`proxplan.identify.strata`) on top of
the calibrated model and scored on the validation flights (the manifest's ``split: validation``
flights, best another day's; else flights carved from the train flights, :func:`validation_split`).
A candidate is kept only when

* its gain holds on the validation flights: it cuts their F_z (or yaw) RMSE by ``min_gain`` without
  making the other channel worse by more than 1 %, and
* its parameters are identified: the 2-sigma interval of at least one of its strength parameters
  (:data:`proxplan.physics.effects.EFFECT_STRENGTHS`, whose zero switches it off) excludes zero.

The greedy search keeps the best such candidate per round; afterwards every kept effect must still
bring ``min_gain`` on validation given all the others (else it is dropped as redundant). Every trial
says why it was kept or rejected (``reason``). Test flights only report (each trial's test error is in
the JSON), they never choose.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from proxplan.identify.calibrate import CalibrationResult, ParamSpec, fit_parameters
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
from proxplan.identify.strata import stratified_sample
from proxplan.physics import EFFECT_STRENGTHS, PARAMETERS, Effect, base_wrench

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
    local_gain_fz: float = 0.0  # same as gain_fz on the validation samples where the effect acts, -
    local_gain_tz: float = 0.0  # same for yaw, -
    identified: bool = True  # some strength parameter's 2-sigma interval excludes zero
    strengths: dict[str, Any] = field(default_factory=dict)  # param -> value, std, at_bound; amplitude_sigmas, pinned
    reason: str = ""  # why it was kept or rejected

    def to_json(self) -> dict[str, Any]:
        return {"name": self.name, "params": self.params, "rmse_fz_N": self.test.rmse_fz_N,
                "rmse_torque_Nm": self.test.rmse_torque_Nm, "rmse_tz_Nm": self.test.rmse_tz_Nm,
                "rmse_fz_N_validation": None if self.valid is None else self.valid.rmse_fz_N,
                "gain_fz": self.gain_fz, "gain_tz": self.gain_tz, "round": self.round, "selected": self.selected,
                "local_gain_fz": self.local_gain_fz, "local_gain_tz": self.local_gain_tz,
                "identified": self.identified, "strengths": self.strengths, "reason": self.reason}  # fmt: skip


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


LOCAL_THRESHOLD = (1e-3, 2e-5)
"""An effect acts on a validation sample where it moves the prediction by more than this: 1e-3 N (0.1 g)
of F_z, 2e-5 N m of yaw torque (the smallest structure worth a term, as in discovery)."""
LOCAL_FACTOR = 2.0
"""An effect whose pooled validation gain is diluted (it acts on a small part of the flights) is kept when
it cuts the error by this many times min_gain where it acts (10 % at the default 5 %) ... -"""
LOCAL_POOLED_SHARE = 0.2
"""... and the pooled validation RMSE by this share of min_gain (1 % at the default 5 %), -."""

_START_GRID: dict[str, list[dict[str, float]]] = {
    "wake_advection": [
        {"wind_x_mps": wx, "wind_y_mps": wy} for wx in (-2.0, -1.0, 0.0, 1.0, 2.0) for wy in (-2.0, -1.0, 0.0, 1.0, 2.0)
    ],
    "near_field": [{"decay_L": d, "amplitude": a} for d in (1.0, 3.0, 10.0) for a in (0.3, 1.0, 3.0)],
    "ground_effect": [{"gain_k": k} for k in (0.5, 2.0, 3.5)],
    "ground_jet": [{"decay_L": d, "amplitude_1": a} for d in (1.0, 4.0, 10.0) for a in (0.2, 0.6)],
    "floor_stagnation": [{"decay_widths": d, "amplitude_1": a} for d in (0.3, 1.0, 3.0) for a in (0.3, 1.0)],
    "climb_inflow": [{"gain_1": g} for g in (0.3, 2.0)],
}
"""Extra start points per effect (parameters not named keep their defaults)."""


def fit_effect(
    name: str, units: Sequence[Unit], model: Model, *, options: IdentifyOptions
) -> tuple[Effect, Model, CalibrationResult, float]:
    """Fit one candidate effect (and the thrust scales) on train ``units`` (a stratified, weighted
    sample of them); returns it, the model with it, the fit (values, widened standard deviations) and
    the amplitude of its whole contribution in sigmas (see :func:`identification`)."""
    fit_units = stratified_sample(units, options.max_effect_fit_samples, model.vehicles)
    sw = np.sqrt(np.concatenate([u.weight for u in fit_units]))  # weights of the stratified sample
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
        return np.concatenate([sw * (pf - fz) / s_f, sw * (pt - tz) / s_t])

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
    # the whole contribution's amplitude in sigmas: the fitted effect g (weighted, normalised as the
    # residual) scaled by alpha; alpha = 1 +- s / ||g|| (widened for autocorrelation like the parameters)
    r_fit = residual(result.values)
    g = r_fit - np.concatenate([sw * (f0 - fz) / s_f, sw * (t0 - tz) / s_t])
    s2 = float(r_fit @ r_fit) / max(r_fit.size - len(specs), 1)
    sigmas = float(np.linalg.norm(g) / (np.sqrt(s2) * result.std_inflation)) if s2 > 0 else float("inf")
    return m.effects[-1], m, result, sigmas


WHOLE_SIGMAS = 5.0
"""An effect whose whole fitted contribution stands this many sigma clear of zero is identified even when
its parameters trade off against each other (each interval wide, e.g. thrust_bias's force against its
thrust scales in hover), -."""
DEGENERATE_REL = 100.0
"""A strength parameter whose std exceeds this many times its value is degenerate with another (only
a combination acts, e.g. wind over convection speed): the effect's whole amplitude is judged instead."""


def identification(name: str, fit: CalibrationResult, amplitude_sigmas: float) -> tuple[bool, dict[str, Any]]:
    """Whether a fitted effect is identified, and the record (module docstring of the pipeline, docs):

    * a strength parameter (:data:`proxplan.physics.effects.EFFECT_STRENGTHS`) off its bounds has a
      2-sigma interval that excludes zero; when every strength parameter is pinned on a bound (no
      interval) or degenerate with another (:data:`DEGENERATE_REL`: only a combination acts), the
      effect's whole fitted contribution must stand ``amplitude_sigmas`` > 2 sigma clear of zero;
    * no other fitted parameter (a thrust scale) is pinned on its bound: the fit then wants something
      outside the effect's physical range, i.e. it is bending the effect to stand for another.
    """
    strengths = [k for k in EFFECT_STRENGTHS.get(name, ()) if k in fit.names]
    info: dict[str, Any] = {}
    for i, k in enumerate(fit.names):
        std = float(fit.std[i])
        info[k] = {"value": float(fit.values[i]), "std": std if np.isfinite(std) else None,
                   "at_bound": bool(fit.at_bound[i]) if fit.at_bound else False}  # fmt: skip

    def free(k: str) -> bool:  # off its bounds with a meaningful interval
        d = info[k]
        return not d["at_bound"] and d["std"] is not None and d["std"] <= DEGENERATE_REL * abs(d["value"])

    usable = [k for k in strengths if free(k)]
    strong = any(fit.interval_excludes(k) for k in usable) if usable else amplitude_sigmas > 2.0
    strong |= amplitude_sigmas > WHOLE_SIGMAS  # parameters that trade off (a bias against a thrust scale)
    pinned = [k for k in fit.names if k not in strengths and info[k]["at_bound"]]
    info["amplitude_sigmas"] = amplitude_sigmas
    info["pinned"] = pinned
    return strong and not pinned, info


def _interval_text(info: dict[str, Any]) -> str:
    parts = [f"{k} = {d['value']:.3g}" + (" (on its bound)" if d["at_bound"] else
                                          f" +- {2 * d['std']:.2g}" if d["std"] is not None else " (std n/a)")
             for k, d in info.items() if isinstance(d, dict)]  # fmt: skip
    if "amplitude_sigmas" in info:
        parts.append(f"contribution {info['amplitude_sigmas']:.1f} sigma")
    if info.get("pinned"):
        parts.append(f"pinned on a bound: {', '.join(info['pinned'])}")
    return ", ".join(parts)


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
    """Greedy effect selection by VALIDATION error and identification, then pruning (module docstring).

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

    def valid_predictions(m: Model) -> np.ndarray:
        """(M, 2) predicted F_z (N) and yaw torque (N m) on the validation sample."""
        set_errors(m, valid_eval)  # fills the base cache
        bases = cache[(id(m.vehicles), id(valid_eval))][1]
        preds = [predict(u, m, base=b) for u, b in zip(valid_eval, bases)]
        return np.column_stack(
            [np.concatenate([p[0][:, 2] for p in preds]), np.concatenate([p[1][:, 2] for p in preds])]
        )

    measured = np.column_stack([np.concatenate([u.force_N[:, 2] for u in valid_eval]),
                                np.concatenate([u.torque_Nm[:, 2] for u in valid_eval])])  # fmt: skip

    def local_gains(cand: Model, base: Model) -> tuple[float, float]:
        """Gains of ``cand`` over ``base`` on the validation samples where they differ (the effect acts:
        by more than LOCAL_THRESHOLD per channel); 0 where it acts nowhere."""
        pc, pb = valid_predictions(cand), valid_predictions(base)
        out = []
        for k, floor in enumerate((1e-6, 1e-7)):
            acts = np.abs(pc[:, k] - pb[:, k]) > LOCAL_THRESHOLD[k]
            if not acts.any():
                out.append(0.0)
                continue
            rc = float(np.sqrt(np.mean((measured[acts, k] - pc[acts, k]) ** 2)))
            rb = float(np.sqrt(np.mean((measured[acts, k] - pb[acts, k]) ** 2)))
            out.append(_gain(rc, rb, floor))
        return out[0], out[1]

    def gains(new: Errors, current: Errors) -> tuple[float, float]:
        return _gain(new.rmse_fz_N, current.rmse_fz_N, 1e-6), _gain(new.rmse_tz_Nm, current.rmse_tz_Nm, 1e-7)

    def holds(
        gf: float, gt: float, own: tuple[float, float] | None = None, local: tuple[float, float] | None = None
    ) -> bool:
        """The gains (vs the current model) reach min_gain — or, for an effect acting on a small part of
        the flights (whose pooled gain it dilutes), LOCAL_FACTOR x min_gain where it acts (``local``) and
        LOCAL_POOLED_SHARE of min_gain pooled — and the effect itself (vs the model it was fitted on,
        ``own``; default the same gains) makes no channel worse by more than 1 %."""
        pooled = max(gf, gt)
        enough = pooled >= options.min_gain or (
            local is not None
            and max(local) >= LOCAL_FACTOR * options.min_gain
            and pooled >= LOCAL_POOLED_SHARE * options.min_gain
        )
        return enough and min(own or (gf, gt)) > -0.01

    scored = [(valid_errors(m), m) for m in starts]
    current, model = min(scored, key=lambda em: em[0].rmse_fz_N / max(scored[0][0].rmse_fz_N, 1e-12)
                         + em[0].rmse_tz_Nm / max(scored[0][0].rmse_tz_Nm, 1e-15))  # fmt: skip
    start_scales = dict(model.thrust_scale)
    trials: list[EffectTrial] = []
    # library names are fitted here; Effects (options.extra_candidates, e.g. data-driven terms
    # fitted elsewhere on the fitting flights) are scored with their parameters as given
    remaining: list[str | Effect] = [*options.effects, *options.extra_candidates]
    rnd = 0
    while remaining and len(model.effects) < options.max_effects:
        rnd += 1
        bases = [m for _, m in scored] if rnd == 1 else [model]
        round_trials = []
        base_errors = {id(b): valid_errors(b) for b in bases}
        for item in progress_bar(remaining, f"effects round {rnd}", options.progress):
            best_here = None
            for base in bases:
                info: dict[str, Any]
                if isinstance(item, Effect):
                    eff, cand = item, replace(base, effects=base.effects + (item,))
                    ident, info = True, {}
                else:
                    eff, cand, fit, sigmas = fit_effect(item, train, base, options=options)
                    ident, info = identification(item, fit, sigmas)
                err = valid_errors(cand)
                gf, gt = gains(err, current)
                if best_here is None or gf + gt > best_here[0].gain_fz + best_here[0].gain_tz:
                    trial = EffectTrial(eff.name, eff.full_params(), rnd, err, gf, gt, valid=err, identified=ident,
                                        strengths=info)  # fmt: skip
                    best_here = (trial, cand, item, gains(err, base_errors[id(base)]), base)
            assert best_here is not None  # at least one candidate per round
            t, cand, item, own, base = best_here
            local = local_gains(cand, base)
            round_trials.append((replace(t, local_gain_fz=local[0], local_gain_tz=local[1]), cand, item, own))
        ok = [(t, c, i) for t, c, i, own in round_trials
              if holds(t.gain_fz, t.gain_tz, own, (t.local_gain_fz, t.local_gain_tz)) and t.identified]  # fmt: skip
        best = max(ok, key=lambda tci: tci[0].gain_fz + tci[0].gain_tz, default=None)
        for t, c, _, own in round_trials:
            chosen = best is not None and t is best[0]
            ok_gain = holds(t.gain_fz, t.gain_tz, own, (t.local_gain_fz, t.local_gain_tz))
            reason = _reason(t, ok_gain, min(own) <= -0.01, chosen, best[0].name if best else "")
            trials.append(replace(t, selected=chosen, test=set_errors(c, test_eval), reason=reason))
        if best is None:
            break
        model, current = best[1], best[0].valid or best[0].test
        remaining.remove(best[2])
    model, trials = _prune(model, trials, start_scales, valid_errors, gains, holds, local_gains)
    return model, trials


def _reason(t: EffectTrial, gain_holds: bool, harms: bool, chosen: bool, winner: str) -> str:
    """Why a trial of one round was kept or rejected (before pruning); ``harms``: the effect makes a
    channel worse by more than 1 %."""
    gain = (f"validation gain F_z {t.gain_fz:+.1%}, yaw {t.gain_tz:+.1%} "
            f"(where it acts: {t.local_gain_fz:+.1%}, {t.local_gain_tz:+.1%})")  # fmt: skip
    if chosen:
        return f"kept: {gain}; identified ({_interval_text(t.strengths) or 'fitted elsewhere'})"
    if not gain_holds:
        if harms:
            return f"rejected: {gain}: makes a channel worse by more than 1 %"
        return f"rejected: {gain}: the gain does not hold on the validation flights"
    if not t.identified:
        why = "a parameter is pinned on its bound" if t.strengths.get("pinned") else "the 2-sigma interval includes 0"
        return f"rejected: not identified, {why} ({_interval_text(t.strengths)})"
    return f"not kept this round: {gain}, but {winner} gained more"


def _prune(model: Model, trials: list[EffectTrial], start_scales: dict, valid_errors, gains, holds, local_gains):
    """Drop kept effects that no longer bring ``min_gain`` on validation given all the others (the same
    test as when they were kept, pooled or where they act; the one bringing the least first, then
    check again); their trial says so."""
    while True:
        current = valid_errors(model)
        weakest = None
        for eff in model.effects:
            without = replace(model, effects=tuple(e for e in model.effects if e is not eff))
            if eff.name == "thrust_bias":  # its per-type thrust scales go with it
                without = replace(without, thrust_scale=dict(start_scales))
            gf, gt = gains(current, valid_errors(without))  # what eff cuts, given the others
            if not holds(gf, gt, None, local_gains(model, without)) and (
                weakest is None or gf + gt < weakest[1] + weakest[2]
            ):
                weakest = (eff, gf, gt, without)
        if weakest is None:
            return model, trials
        eff, gf, gt, model = weakest
        others = ", ".join(e.name for e in model.effects) or "none"
        trials = [replace(t, selected=False, reason=f"dropped: redundant given {others} (validation gain F_z "
                                                        f"{gf:+.1%}, yaw {gt:+.1%} with them)")
                  if t.selected and t.name == eff.name else t for t in trials]  # fmt: skip
