"""Stages 5 and 6 of the pipeline around one reference model: the library effects, the discovered terms, and
the two judged together (issue 35; :mod:`proxplan.identify.effect_selection`, :mod:`proxplan.identify.discovery`,
the held-out tests of :mod:`proxplan.identify.crossval`)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from proxplan.identify.calibrate import ParamSpec, calibrate_model
from proxplan.identify.channel_variance import structural_row_weight
from proxplan.identify.crossval import heldout_mse, heldout_predictions, solve_carried, trainable_groups
from proxplan.identify.data import IdentifyOptions, Model, Unit, predict
from proxplan.identify.delayed import delayed_units
from proxplan.identify.design import selection_set, tangent_u
from proxplan.identify.discovery import DISCOVERED_NAME, DiscoveryResult, discover_terms
from proxplan.identify.effect_selection import THRUST_BIAS, EffectSelection, EffectSelector
from proxplan.identify.heldout_select import Candidate, ForwardResult, heldout_backward
from proxplan.identify.noise import CHANNELS, NoiseLevel, stacked
from proxplan.physics import Effect


@dataclass
class Selection:
    """Effects and discovered terms chosen around one reference model (:func:`select_and_discover`): the
    final model, the library selection and the discovery, which reference they started from, the
    held-out MSE of the final set per group (noise units) and the groups' note."""

    model: Model
    effects: EffectSelection
    discovery: DiscoveryResult | None
    start: str  # "calibrated" | "prior"
    heldout_mse: np.ndarray  # (groups, channels), noise units
    note: str
    cluster: np.ndarray  # (groups,) int, each held-out group's flight (crossval.GroupPlan.cluster)
    rows: list[Unit]  # the selection's samples (stratified train sample and validation sample)
    heldout_fz_N: np.ndarray  # (N,) each row's held-out F_z residual, N (rows in the order of ``rows``)
    # type -> (4,) held-out MSE per channel (noise units) of the kept set: what sets the delivered fit's channel
    # weights (identify.channel_variance); well above 1: structure in that channel nothing kept explains
    channel_mse: dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def heldout_total(self) -> float:
        """Mean over the held-out groups of the sum over channels of ln(held-out MSE): the score two starts
        are compared by (scale-free, every log and channel alike), lower is better."""
        per_group = self.group_totals()
        per_group = per_group[np.isfinite(per_group)]
        return float(np.mean(per_group)) if per_group.size else float("inf")

    def group_totals(self) -> np.ndarray:
        """(groups,) each held-out group's sum over channels of ln(held-out MSE) (NaN: no channel)."""
        m = np.where(np.isfinite(self.heldout_mse) & (self.heldout_mse > 0), np.log(np.abs(self.heldout_mse)), np.nan)
        return np.where(np.any(np.isfinite(m), axis=1), np.nansum(m, axis=1), np.nan)

    def to_json(self) -> dict[str, Any]:
        stab = self.effects.stability
        out: dict[str, Any] = {"start": self.start, "groups": self.note, "heldout_log_mse": self.heldout_total,
               "effects_stability_threshold": stab.threshold, "effects_mean_chosen_per_half": stab.mean_chosen,
               "effects_expected_false_bound": stab.expected_false_bound,
               "half_samples": stab.n_halves, "recalibration_step_u": self.effects.steps,
               "indistinguishable": self.effects.rivals_json(),
               "channel_heldout_mse": {t: dict(zip(CHANNELS, (None if not np.isfinite(v) else float(v) for v in m)))
                                       for t, m in self.channel_mse.items()}}  # fmt: skip
        if self.discovery is not None:
            d = self.discovery.stability
            out |= {
                "terms_stability_threshold": d.threshold,
                "terms_mean_chosen_per_half": d.mean_chosen,
                "terms_expected_false_bound": d.expected_false_bound,
            }
        return out


def select_and_discover(
    fit: Sequence[Unit],
    valid: Sequence[Unit],
    reference: Model,
    specs: Sequence[ParamSpec],
    *,
    options: IdentifyOptions,
    noise: NoiseLevel,
    test: Sequence[Unit] = (),
    start: str = "calibrated",
    calibrated_thrust_scale: Mapping[str, float] | None = None,
    prior_model: Model | None = None,
) -> Selection:
    """Stages 5 and 6 around ``reference`` (module docstring): the library effects, then the discovered
    terms with the kept effects and the vehicle parameters' tangents refitted jointly, in the noise units
    of ``noise``. ``calibrated_thrust_scale`` (type -> scale) are the thrust scales the calibration fitted
    beside ``reference``'s parameters (on every train sample); they stand with it when nothing is kept. With
    ``prior_model`` (the calibration's priors), a model that keeps something is polished (:func:`polished`)."""
    sel = selection_set(fit, valid, reference, noise, max_fit_samples=options.max_fit_samples,
                        max_valid_samples=options.max_eval_samples,
                        measure=options.measure if options.smoothed_prediction else None)  # fmt: skip
    selector = EffectSelector(sel, specs, options=options)
    selector.fit_candidates(options.effects)
    effects = selector.run(test=test)
    discovery = None
    if options.discover:
        discovery = discover_terms(sel, selector.always_columns(effects.selected), selector.ridge_for)
    jf = joint_model(selector, effects, discovery)
    model, heldout, joint, heldout_fz = jf.model, jf.heldout_mse, jf.backward, jf.heldout_fz_N
    if discovery is not None:
        standing = discovery.keys_of(joint.chosen)
        discovery.kept = {k: v for k, v in discovery.kept.items() if k in standing}
        discovery.forward.dropped.update({k: t for k, t in joint.dropped.items() if k in discovery.groups})
    for trial in effects.trials:
        if trial.name in joint.dropped:
            t = joint.dropped[trial.name]
            trial.selected = False
            trial.reason = (f"dropped: redundant given the discovered terms (held-out gain {t.mean:+.3g} +- {t.se:.2g}, "
                            f"needs > {t.z:.2f} SE)")  # fmt: skip
    effects.selected = [n for n in effects.selected if n in joint.chosen or n == THRUST_BIAS]
    beyond_thrust = [n for n in effects.selected if n != THRUST_BIAS]
    terms_kept = discovery is not None and bool(discovery.kept)
    if start == "calibrated" and not beyond_thrust and not terms_kept:
        # nothing kept: the calibration's own MAP fit (nonlinear, on every train sample) stands; the joint
        # step exists to refit the vehicle parameters beside kept candidates, and alone it is only the
        # first-order, subsampled copy of that fit (steps of 1e-4 in ln theta that float32 rounding moves).
        # With it stand the thrust scales it fitted (the nuisance it set back to 1 in ``reference``), when
        # thrust_bias is asked for.
        if THRUST_BIAS in options.effects and calibrated_thrust_scale is not None:
            reference = replace(reference, thrust_scale=dict(calibrated_thrust_scale),
                                effects=(*reference.effects, Effect(THRUST_BIAS, {"force_z_N": 0.0})))  # fmt: skip
        model = reference
    elif prior_model is not None and options.calibrate and not terms_kept:
        # not with discovered terms: a term on a base feature (base_fz_lag...) was fitted on the base at the
        # reference, and refitting the base under it changes what the term means (and each evaluation of
        # the features costs: on the shipped manifest the polish doubled selection's time)
        model = polished(selector, model, fit, prior_model, options=options, noise=noise, row_weight=jf.row_weight)
    return Selection(model, effects, discovery, start, heldout, sel.plan.note, sel.plan.cluster, sel.units, heldout_fz,
                     jf.channel_mse)  # fmt: skip


def fz_only(column: np.ndarray) -> np.ndarray:
    """(N, 4) ``column`` (noise units, channels :data:`proxplan.identify.noise.CHANNELS`) with its torque
    channels zeroed: the column acts on F_z alone."""
    out = np.zeros_like(column)
    out[:, 0] = column[:, 0]
    return out


CARRIED_SUFFIX = "|torque_part"
"""Suffix of the name of a vehicle parameter's tangent restricted to the torque channels, carried at the
coefficient its F_z part is fitted with (:func:`joint_model`, :func:`proxplan.identify.crossval.solve_carried`)."""

STEP_FRACTIONS = (1.0, 0.5, 0.25, 0.125, 0.0)
"""Fractions of the vehicle parameters' joint step tried on the nonlinear model (:func:`_line_searched`)."""


def _line_searched(
    selector: EffectSelector,
    coef: dict[str, float],
    chosen: Sequence[str],
    terms: dict[str, float],
    penalty: dict[str, tuple[float, float]],
    terms_part: np.ndarray | None = None,
    row_weight: np.ndarray | None = None,
) -> Model:
    """The joint fit's model, its vehicle-parameter step taken only as far as the NONLINEAR model confirms.
    The joint fit is one Gauss-Newton step on tangents linearised at the reference; a large step (the prior
    start moving b_v by exp(-1.4)) leaves the region where they hold, and the stepped model then predicts
    worse than the linear fit promised. So the model is built at each fraction of :data:`STEP_FRACTIONS` of
    the step (effects and terms at their fitted coefficients; ``terms_part`` the terms' contribution, (N, 4)
    noise units) and the one with the lowest MAP objective on the train rows is kept: weighted squared residual in noise units over tau
    (each row and channel times ``row_weight``, :mod:`proxplan.identify.channel_variance`), plus the tangents' prior
    penalty precision (alpha step - center)^2 (backtracking line search, Nocedal & Wright ch. 3)."""
    best: tuple[float, Model] | None = None
    # a thrust scale enters the prediction linearly in its u = 1 - 1/s (design.thrust_scale_u: its column is
    # exact): only the other steps are searched
    stepped = {k for k in penalty if not k.endswith(".thrust_scale")}
    for alpha in STEP_FRACTIONS:
        c = {k: (alpha * v if k in stepped else v) for k, v in coef.items()}
        model = selector.model_with(c, chosen)
        if terms:
            model = replace(model, effects=model.effects + (Effect(DISCOVERED_NAME, terms),))
        score = map_objective(selector, model, penalty, terms_part, row_weight)
        if best is None or score < best[0]:
            best = (score, model)
    assert best is not None
    return best[1]


def map_objective(
    selector: EffectSelector,
    model: Model,
    penalty: dict[str, tuple[float, float]],
    terms: np.ndarray | None = None,
    row_weight: np.ndarray | None = None,
) -> float:
    """The MAP objective of ``model`` on the selection's train rows, -: the weighted squared residual of the
    four channels in noise units over tau (each row and channel times ``row_weight`` (N, 4), the delivered
    fit's weights of :mod:`proxplan.identify.channel_variance`; None: 1), plus each always-fitted parameter's prior penalty, precision
    (u - u_ref - center)^2 (u the parameter's coordinate, :func:`proxplan.identify.design.tangent_u`).

    The selection's stratified rows are sparse and out of order in time, so what needs the clock is taken
    where it is exact: a delayed library effect on each row's delayed state
    (:func:`proxplan.identify.delayed.delayed_unit`), the discovered terms as ``terms`` ((N, 4) noise units,
    their columns at their coefficients, the features computed on the full-rate flights; read through each
    type's thrust scale, :func:`proxplan.identify.data.thrust_scaled`)."""
    sel = selector.sel
    train = (~sel.plan.held_out_only[sel.group]) * sel.weight
    plain = replace(model, effects=tuple(e for e in model.effects if e.name != DISCOVERED_NAME))
    lags = {e.lag_s for e in plain.effects}
    delayed = delayed_units(sel.units, sel.sources, sorted(lags))
    predicted = np.concatenate([stacked(*predict(u, plain, delayed=d)) for u, d in zip(sel.units, delayed)])
    r = (sel.measured - predicted) / sel.row_scale
    if terms is not None:
        scale = np.concatenate([np.full(len(u), model.thrust_scale.get(u.type, 1.0)) for u in sel.units])
        r -= terms / scale[:, None]
    if row_weight is not None:
        r = r * row_weight
    data = float(np.sum(train[:, None] * np.where(np.isfinite(r), r, 0.0) ** 2)) / sel.tau
    step = {s.name: tangent_u(model, s) - tangent_u(sel.model, s) for s in selector.specs}
    return data + sum(p * (step[k] - c0) ** 2 for k, (p, c0) in penalty.items())


def polished(
    selector: EffectSelector,
    model: Model,
    fit: Sequence[Unit],
    prior_model: Model,
    *,
    options: IdentifyOptions,
    noise: NoiseLevel,
    row_weight: np.ndarray | None = None,
) -> Model:
    """``model`` (after the joint step) or, when its MAP objective (:func:`map_objective`, rows and channels
    weighted by ``row_weight``, the joint fit's) is lower, the same
    effects with the vehicle parameters and thrust scales refitted by the calibration's own NONLINEAR MAP fit
    on every train sample (:func:`proxplan.identify.calibrate.calibrate_model`, priors of ``prior_model``,
    started at ``model``, its effects held). The joint step is one linearised step on a subsample: on
    generated logs with an own-velocity force it left the calibrated Parrot's test error at 0.26 g where the
    calibration's own fit, with nothing to keep, gave 0.18 g on the same logs without the force."""
    _, _, refit = calibrate_model(fit, prior_model, options=options, noise=noise, start=model)
    penalty = _penalty(selector)
    before = map_objective(selector, model, penalty, row_weight=row_weight)
    return refit if map_objective(selector, refit, penalty, row_weight=row_weight) < before else model


def _penalty(selector: EffectSelector) -> dict[str, tuple[float, float]]:
    """Always-fitted column -> (prior precision, center) of the selection's ridge."""
    ridge = selector.ridge_for(selector.always)
    return {k: (float(ridge.precision[i]), float(ridge.center[i])) for i, k in enumerate(selector.always)}


SCORE_RESOLUTION = 1e-3
"""Smallest difference of :attr:`Selection.heldout_total` (mean over held-out groups of the summed ln(held-out
MSE), -) that picks a start: 1e-3 is 0.05 % of RMSE on one channel, far below any error that matters and far
above what float32 rounding in a log format moves it (1e-6)."""


def other_start_better(default: Selection, other: Selection) -> bool:
    """Whether ``other`` (the selection around the prior model) predicts the held-out flights better than
    ``default`` (around the calibrated model): a lower :attr:`Selection.heldout_total` by more than
    :data:`SCORE_RESOLUTION`. Both are scored on the same held-out flights, samples and noise units, and
    neither start is the more natural null: the calibration may have absorbed a missing effect into the
    vehicle parameters (its tangents undo that only to first order), or the prior may be off, so the
    better-predicting one is kept (with few flights a test "beyond chance" would keep the calibrated one
    whatever the flights say). Within the resolution the calibrated start stays, so rounding in the inputs
    never picks the model."""
    return other.heldout_total < default.heldout_total - SCORE_RESOLUTION


@dataclass
class JointFit:
    """What :func:`joint_model` delivers: the model; the held-out MSE per group and channel (noise units) of the
    kept set; the backward pass's record; each selection row's held-out F_z residual (N,) N (measured minus the
    prediction of the fit that left its flight out: what the spread's interval is set on); and the rows'
    channel weights (N, 4) the delivered fit used (:mod:`proxplan.identify.channel_variance`), with each
    type's held-out MSE per channel they come from (noise units)."""

    model: Model
    heldout_mse: np.ndarray
    backward: ForwardResult
    heldout_fz_N: np.ndarray
    row_weight: np.ndarray
    channel_mse: dict[str, np.ndarray]


def joint_model(selector: EffectSelector, effects: EffectSelection, discovery: DiscoveryResult | None) -> JointFit:
    """The kept library effects and discovered terms judged together: each must still pass the held-out
    gain test given all the others (a library effect that stood in for an undeclared one is dropped once
    the discovered term explains it better); then the survivors and the vehicle parameters' steps are
    fitted jointly on every train group, each row and channel weighted by its error variance, noise plus
    what the kept set leaves unexplained on flights held out (:mod:`proxplan.identify.channel_variance`).
    Beside kept discovered terms the steps are fitted on F_z alone and carried onto the torque channels at the
    same coefficients (:func:`proxplan.identify.crossval.solve_carried`): the delivered model applies them on
    every channel, so the terms are fitted to what they leave there."""
    sel = selector.sel
    kept = [c.as_candidate() for c in selector.candidates if c.name in effects.selected]
    terms = dict(discovery.kept) if discovery is not None else {}
    groups = dict(discovery.groups) if discovery is not None else {}  # a split term's per-type keys: one candidate
    columns = {k: selector.tangents[k] for k in selector.always}
    for cand in selector.candidates:
        if cand.name in effects.selected:
            columns.update(cand.columns)
    if discovery is not None:
        columns.update({k: discovery.columns[k] for k in terms})
    kept += [Candidate(name, keys) for name, keys in groups.items()]
    sums = sel.sums(columns)
    ridge = selector.ridge_for(sums.columns)
    back = heldout_backward(sums, selector.always, kept, sel.plan, ridge, sel.tau,
                            discovery.fold_eligible if discovery is not None else None)  # fmt: skip
    names = list(selector.always) + [col for c in kept if c.name in back.chosen for col in c.columns]
    idx = sums.index(names)
    x = np.stack([columns[k] for k in sums.columns], axis=2)  # (N, 4, p) in noise units
    held = heldout_predictions(sums, x, sel.group, idx, sel.plan, ridge, sel.tau)
    train = (~sel.plan.held_out_only[sel.group]) * sel.weight
    types = sel.target_types()
    row_weight, channel_mse = structural_row_weight(sel.residual - held, types, train)
    delivered = dict(columns)
    carried: dict[str, str] = {}
    if any(name in back.chosen for name in groups):
        # the delivered fit beside kept discovered terms: the vehicle parameters' tangents on F_z only
        # (they are calibrated on F_z); on all four channels they bend to fit roll and pitch, which the
        # kept torque terms are for, and lose F_z on flights held out (docs/identify.md, stop 58). Judged
        # (held-out errors below, the start choice) with the full tangents, as selection was. The delivered
        # model applies the steps on every channel, so their torque parts are carried at the F_z-fitted
        # coefficients, and the terms are fitted to what the steps leave on roll and pitch (stop 73: with the
        # steps' torque left in the target, a torque term counted it twice, 2.1x on bench draw 29001)
        delivered |= {k: fz_only(columns[k]) for k in selector.always}
        carried = {k: f"{k}{CARRIED_SUFFIX}" for k in selector.always}
        delivered |= {carried[k]: columns[k] - delivered[k] for k in selector.always}
    deliver = sel.sums({k: v * row_weight for k, v in delivered.items()}, target=sel.residual * row_weight)
    drag = np.array([deliver.index([carried[k]])[0] if k in carried else -1 for k in names], dtype=int)
    beta = solve_carried(deliver, deliver.index(names), drag, trainable_groups(deliver, sel.plan), ridge, sel.tau)
    coef = dict(zip(names, (float(b) for b in beta)))
    survivors = {k: coef[k] for name, keys in groups.items() if name in back.chosen for k in keys}
    chosen = [n for n in effects.selected if n in back.chosen]
    terms_part = sum((v * columns[k] for k, v in survivors.items()), np.zeros_like(sel.residual))
    model = _line_searched(selector, coef, chosen, survivors, _penalty(selector), terms_part, row_weight)
    if survivors and discovery is not None:
        discovery.kept = survivors
    residual_fz = (sel.residual[:, 0] - held[:, 0]) * sel.row_scale[:, 0]
    return JointFit(model, heldout_mse(sums, idx, sel.plan, ridge, sel.tau), back, residual_fz, row_weight,
                    channel_mse)  # fmt: skip
