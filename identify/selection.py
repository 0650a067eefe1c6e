"""Stages 5 and 6 of the pipeline around one reference model: the library effects, the discovered terms, and
the two judged together (issue 35; :mod:`proxplan.identify.effect_selection`, :mod:`proxplan.identify.discovery`,
the held-out tests of :mod:`proxplan.identify.crossval`)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from proxplan.identify.calibrate import ParamSpec
from proxplan.identify.crossval import Candidate, ForwardResult, heldout_backward, heldout_mse, solve, trainable_groups
from proxplan.identify.data import IdentifyOptions, Model, Unit
from proxplan.identify.design import selection_set
from proxplan.identify.discovery import DISCOVERED_NAME, DiscoveryResult, discover_terms
from proxplan.identify.effect_selection import EffectSelection, EffectSelector
from proxplan.identify.noise import NoiseLevel
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

    @property
    def heldout_total(self) -> float:
        """Mean over the held-out groups of the sum over channels of ln(held-out MSE): the score two starts
        are compared by (scale-free, every log and channel alike), lower is better."""
        m = np.where(np.isfinite(self.heldout_mse) & (self.heldout_mse > 0), np.log(np.abs(self.heldout_mse)), np.nan)
        per_group = np.nansum(m, axis=1)[np.any(np.isfinite(m), axis=1)]
        return float(np.mean(per_group)) if per_group.size else float("inf")

    def to_json(self) -> dict[str, Any]:
        stab = self.effects.stability
        out: dict[str, Any] = {"start": self.start, "groups": self.note, "heldout_log_mse": self.heldout_total,
               "effects_stability_threshold": stab.threshold, "effects_mean_chosen_per_half": stab.mean_chosen,
               "effects_expected_false_bound": stab.expected_false_bound,
               "half_samples": stab.n_halves, "recalibration_step_u": self.effects.steps}  # fmt: skip
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
) -> Selection:
    """Stages 5 and 6 around ``reference`` (module docstring): the library effects, then the discovered
    terms with the kept effects and the vehicle parameters' tangents refitted jointly, in the noise units
    of ``noise``."""
    sel = selection_set(fit, valid, reference, noise, max_fit_samples=options.max_fit_samples,
                        max_valid_samples=options.max_eval_samples)  # fmt: skip
    selector = EffectSelector(sel, specs, options=options)
    selector.fit_candidates(options.effects)
    effects = selector.run(test=test)
    discovery = None
    if options.discover:
        discovery = discover_terms(sel, selector.always_columns(effects.selected), selector.ridge_for)
    model, heldout, joint = joint_model(selector, effects, discovery)
    if discovery is not None:
        discovery.kept = {k: v for k, v in discovery.kept.items() if k in joint.chosen}
        discovery.forward.dropped.update({k: t for k, t in joint.dropped.items() if k in discovery.columns})
    for trial in effects.trials:
        if trial.name in joint.dropped:
            t = joint.dropped[trial.name]
            trial.selected = False
            trial.reason = (f"dropped: redundant given the discovered terms (held-out gain {t.mean:+.3g} +- {t.se:.2g}, "
                            f"needs > {t.z:.2f} SE)")  # fmt: skip
    effects.selected = [n for n in effects.selected if n in joint.chosen]
    return Selection(model, effects, discovery, start, heldout, sel.plan.note)


def joint_model(
    selector: EffectSelector, effects: EffectSelection, discovery: DiscoveryResult | None
) -> tuple[Model, np.ndarray, ForwardResult]:
    """The kept library effects and discovered terms judged together: each must still pass the held-out
    gain test given all the others (a library effect that stood in for an undeclared one is dropped once
    the discovered term explains it better); then the survivors and the vehicle parameters' steps are
    fitted jointly on every train group. Returns the model, the held-out MSE per group and channel, and
    the backward pass's record."""
    sel = selector.sel
    kept = [Candidate(c.name, tuple(c.columns)) for c in selector.candidates if c.name in effects.selected]
    terms = dict(discovery.kept) if discovery is not None else {}
    columns = {k: selector.tangents[k] for k in selector.always}
    for cand in selector.candidates:
        if cand.name in effects.selected:
            columns.update(cand.columns)
    if discovery is not None:
        columns.update({k: discovery.columns[k] for k in terms})
    kept += [Candidate(k, (k,)) for k in terms]
    sums = sel.sums(columns)
    ridge = selector.ridge_for(sums.columns)
    back = heldout_backward(sums, selector.always, kept, sel.plan, ridge, sel.tau)
    names = list(selector.always) + [col for c in kept if c.name in back.chosen for col in c.columns]
    idx = sums.index(names)
    beta = solve(sums, idx, trainable_groups(sums, sel.plan), ridge, sel.tau)
    coef = dict(zip(names, (float(b) for b in beta)))
    model = selector.model_with(coef, [n for n in effects.selected if n in back.chosen])
    survivors = {k: coef[k] for k in terms if k in back.chosen}
    if survivors:
        model = replace(model, effects=model.effects + (Effect(DISCOVERED_NAME, survivors),))
        if discovery is not None:
            discovery.kept = survivors
    return model, heldout_mse(sums, idx, sel.plan, ridge, sel.tau), back
