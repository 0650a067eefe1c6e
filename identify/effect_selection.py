"""Library effects: fitted on train flights, judged by flights held out (issue 35).

Stage 5 of :mod:`proxplan.identify.pipeline`. Each candidate of :data:`proxplan.physics.effects.EFFECT_NAMES`
becomes columns of the linear design (:mod:`proxplan.identify.design`) around the reference model
(built in :mod:`proxplan.identify.effect_candidates`):

* its shape (a decay length, a wind direction, ...) is fitted first, MAP with its priors
  (:func:`proxplan.identify.priors.effect_prior`), on the train rows of the selection set;
* then its strength enters linearly — one column per unit of strength at that shape (``scale``), one
  column per parameter for an effect linear in several (``own_velocity``).

The vehicle parameters' tangent columns are always in, with their priors: every fit recalibrates
jointly with the candidate. ``thrust_bias`` (when the options list it) is not a candidate but a NUISANCE
parameter fitted beside every candidate: one thrust scale per vehicle type (a thrust map's error is per
type, relative to its thrust), MAP with its prior (:mod:`proxplan.identify.priors`, N(1, 0.1)). A thrust
map is never exact, and a scale left out of the design is taken up by whatever candidate correlates with
it (a place in the room standing in for a thrust error, or an effect whose share of the thrust varies
from flight to flight making the scale itself fail the held-out test); with its prior, a scale the data
do not inform stays at 1 and pins nothing out. :class:`EffectSelector` then runs the two tests of
:mod:`proxplan.identify.crossval`: the held-out gain test (every flight predicted by a fit without it;
Bonferroni over a round's candidates) in a greedy forward pass with a backward check, and stability
selection over complementary half-samples of the flights. A candidate is kept only when it passes
both. Every trial says why it was kept or rejected; test flights only report.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from proxplan.identify.calibrate import ParamSpec
from proxplan.identify.consensus import represented_shares, sets_standing_for, split_vote_eligible
from proxplan.identify.crossval import GroupSums, Ridge, heldout_mse, solve, trainable_groups
from proxplan.identify.data import Errors, IdentifyOptions, Model, Unit, errors, progress_bar
from proxplan.identify.delay_profile import (
    LAG_GRID_S,
)
from proxplan.identify.design import (
    LagInputs,
    SelectionSet,
    apply_tangent_step,
    is_thrust_scale,
    lag_inputs,
    tangent_columns,
    tangent_ridge,
)
from proxplan.identify.effect_candidates import EffectCandidate, effect_candidate
from proxplan.identify.heldout_select import ForwardResult, GainTest, heldout_forward
from proxplan.identify.stability import Stability, stability
from proxplan.physics import Effect

THRUST_BIAS = "thrust_bias"
MAX_EFFECTS = 3
"""At most this many library effects are kept (a forward pass stops there)."""


@dataclass
class EffectTrial:
    """The record of one candidate: its fitted parameters (at the coefficient of its held-out test alone),
    the held-out gain test of the first round (alone on the reference) and of the last time it was
    tested, its inclusion probability, whether it was kept and why, and its test error (reported only)."""

    name: str
    params: dict[str, float]
    round: int
    test: Errors | None
    gain_alone: GainTest | None
    gain_last: GainTest | None
    inclusion: float
    selected: bool = False
    reason: str = ""
    shape: dict[str, Any] = field(default_factory=dict)  # the shape fit's parameter report (priors)
    represented: float = 0.0  # share of halves that picked it or an effect standing for it (consensus rule)

    def to_json(self) -> dict[str, Any]:
        t = self.test
        return {"name": self.name, "params": self.params, "round": self.round, "selected": self.selected,
                "rmse_fz_N": None if t is None else t.rmse_fz_N, "rmse_torque_Nm": None if t is None else t.rmse_torque_Nm,
                "rmse_tz_Nm": None if t is None else t.rmse_tz_Nm,
                "heldout_gain_alone": None if self.gain_alone is None else self.gain_alone.to_json(),
                "heldout_gain": None if self.gain_last is None else self.gain_last.to_json(),
                "inclusion_probability": self.inclusion, "represented_probability": self.represented,
                "reason": self.reason, "shape_fit": self.shape}  # fmt: skip


@dataclass
class EffectSelection:
    """The outcome: the model with the kept effects (reference + the joint fit's recalibration step + the
    effects at their jointly fitted coefficients), the kept names, every trial, the stability record, the
    held-out MSE per group of the final set (noise units) and the groups' note."""

    model: Model
    selected: list[str]
    trials: list[EffectTrial]
    stability: Stability
    heldout_mse: np.ndarray
    note: str
    steps: dict[str, float]  # the joint fit's step of each vehicle parameter from the reference (u units)
    coefficients: dict[str, float]
    rivals: dict[str, dict[str, GainTest]] = field(default_factory=dict)  # crossval.ForwardResult.rivals

    def rivals_json(self) -> dict[str, dict[str, Any]]:
        """Kept effect -> {rival: the kept one's head-to-head held-out gain over it} (crossval's record)."""
        return {k: {n: t.to_json() for n, t in r.items()} for k, r in self.rivals.items() if k in self.selected}

    @property
    def heldout_total(self) -> float:
        """Mean held-out MSE over the groups (noise units): how two selections (two reference models)
        compare."""
        m = self.heldout_mse[np.isfinite(self.heldout_mse)]
        return float(np.mean(m)) if m.size else float("inf")


class EffectSelector:
    """One selection of library effects around a reference model (module docstring).

    State: the selection set, the always-in tangent columns and their priors, the candidates with their
    columns, the per-group sums of the whole design, and after :meth:`run` the stability record and the
    forward pass."""

    def __init__(self, sel: SelectionSet, specs: Sequence[ParamSpec], *, options: IdentifyOptions):
        self.sel = sel
        self.options = options
        # the thrust scales are always fitted when thrust_bias is asked for (a nuisance: module docstring)
        self.fit_thrust = THRUST_BIAS in options.effects
        self.thrust_specs = [s for s in specs if is_thrust_scale(s)] if self.fit_thrust else []
        self.specs = [s for s in specs if not is_thrust_scale(s)] + self.thrust_specs
        self.tangents = tangent_columns(sel, self.specs)
        self.always = [s.name for s in self.specs]
        self.candidates: list[EffectCandidate] = []
        self.sums: GroupSums | None = None
        self.ridge: Ridge | None = None
        self.delayed: dict[float, LagInputs] = {}  # delay (s) -> the samples' inputs that much earlier
        self.represented: dict[str, float] = {}  # after run: share of halves that picked it or one standing for it
        self.eligible: set[str] = set()  # after run: the effects the held-out test may keep (split_vote_eligible)

    def fit_candidates(self, names: Sequence[str]) -> None:
        stack = (np.stack([self.tangents[k] for k in self.always], axis=2) if self.always
                 else np.zeros((len(self.sel.weight), 4, 0)))  # fmt: skip
        ridge = self.ridge_for(self.always)
        self.delayed = {lag: lag_inputs(self.sel, lag) for lag in LAG_GRID_S}
        for name in progress_bar([n for n in names if n != THRUST_BIAS], "effect shapes", self.options.progress):
            self.candidates.append(effect_candidate(self.sel, name, stack, ridge, self.delayed))

    def design(self) -> tuple[GroupSums, Ridge]:
        if self.sums is None:
            cols = {k: self.tangents[k] for k in self.always}
            for c in self.candidates:
                cols.update(c.columns)
            self.sums = self.sel.sums(cols)
            self.ridge = tangent_ridge(self.sel, self.specs, self.sums.columns)
        assert self.ridge is not None
        return self.sums, self.ridge

    def run(self, *, test: Sequence[Unit] = ()) -> EffectSelection:
        sums, ridge = self.design()
        live = [c for c in self.candidates if c.columns]
        cands = [c.as_candidate() for c in live]
        tau, plan = self.sel.tau, self.sel.plan
        stab = stability(sums, self.always, cands, plan, ridge, tau, max_terms=MAX_EFFECTS)
        # the rule the discovered terms follow (proxplan.identify.consensus.split_vote_eligible): an effect may
        # be kept when most halves picked it, or when most picked it or an effect standing for it and none of
        # those is stable on its own (a split vote). Each eligible effect is its own hypothesis in the
        # Bonferroni count: the named effects are distinct mechanisms, not copies of one feature
        names = [c.name for c in cands]
        stands = sets_standing_for(sums, trainable_groups(sums, plan), self.always, [c.columns for c in cands])
        self.represented = represented_shares(stab, names, stands)
        eligible = self.eligible = split_vote_eligible(stab, names, stands, self.represented)
        # no in-fold selection here (proxplan.identify.stability.fold_eligibility): choosing among the few named
        # effects biases the test little, and with 3 train flights the in-fold halves are single flights, on
        # which a true effect is not picked in every half (docs/identify.md, "Selection inside the fold")
        fwd = heldout_forward(sums, self.always, cands, plan, ridge, tau, max_terms=MAX_EFFECTS, eligible=eligible)
        chosen_cols = self.always + [col for n in fwd.chosen for col in next(c for c in live if c.name == n).columns]
        idx = sums.index(chosen_cols)
        trainable = trainable_groups(sums, plan)
        beta = solve(sums, idx, trainable, ridge, tau)
        coef = dict(zip(chosen_cols, (float(b) for b in beta)))
        model = self.model_with(coef, fwd.chosen)
        trials = self._trials(fwd, stab, test)
        if self.fit_thrust:
            trials.insert(0, self._thrust_trial(model))
        return EffectSelection(model=model, selected=[THRUST_BIAS] * self.fit_thrust + list(fwd.chosen),
                               trials=trials, stability=stab,
                               heldout_mse=heldout_mse(sums, idx, plan, ridge, tau), note=plan.note,
                               steps={k: coef[k] for k in self.always}, coefficients=coef,
                               rivals=fwd.rivals)  # fmt: skip

    def model_with(self, coef: Mapping[str, float], chosen: Sequence[str]) -> Model:
        """The reference model moved by the tangent steps in ``coef`` (column name -> coefficient) with the
        library effects ``chosen`` at their coefficients."""
        model = apply_tangent_step(self.sel.model, self.specs, {k: coef[k] for k in self.always})
        effects = [e for e in model.effects if e.name != THRUST_BIAS]
        if self.fit_thrust:  # the marker that the model's thrust scales were fitted (the effect itself is 0)
            effects.append(Effect(THRUST_BIAS, {"force_z_N": 0.0}))
        effects += [cand.effect_with(coef) for cand in self.candidates if cand.name in chosen]
        return replace(model, effects=tuple(effects))

    def _thrust_trial(self, model: Model) -> EffectTrial:
        """The record of the thrust scales: always fitted, with their prior (module docstring)."""
        types = [s.name.rsplit(".", 1)[0] for s in self.thrust_specs]
        scales = {t: float(model.thrust_scale.get(t, 1.0)) for t in types}
        text = ", ".join(f"{t} {v:.4f}" for t, v in sorted(scales.items()))
        reason = ("kept: a nuisance parameter, always fitted beside every candidate (each vehicle type's thrust "
                  f"scale, logged over delivered thrust, MAP with its prior N(1, 0.1)): {text}")  # fmt: skip
        return EffectTrial(THRUST_BIAS, {"force_z_N": 0.0}, 0, None, None, None, 1.0, True, reason,
                           {"thrust_scale": scales}, 1.0)  # fmt: skip

    def always_columns(self, chosen: Sequence[str]) -> dict[str, np.ndarray]:
        """The columns fitted with every later candidate (discovery): the tangents and the chosen effects', on
        every channel they act on (a delayed effect's roll and pitch too: what discovery looks at is what the
        kept model leaves)."""
        cols = {k: self.tangents[k] for k in self.always}
        for cand in self.candidates:
            if cand.name in chosen:
                cols.update(cand.columns)
        return cols

    def ridge_for(self, names: Sequence[str]) -> Ridge:
        """The tangents' priors over a column list (no prior on the others)."""
        return tangent_ridge(self.sel, self.specs, names)

    def heldout_of(self, always: Mapping[str, np.ndarray], extra: Mapping[str, np.ndarray]) -> np.ndarray:
        """Held-out MSE per group (noise units) of the design ``always`` + ``extra`` fitted together."""
        sums = self.sel.sums({**always, **extra})
        idx = sums.index(list(sums.columns))
        return heldout_mse(sums, idx, self.sel.plan, self.ridge_for(sums.columns), self.sel.tau)

    def _solo(self, cand: EffectCandidate) -> dict[str, float]:
        """Coefficients of the tangent columns and ``cand``'s fitted jointly on every train group."""
        sums, ridge = self.design()
        names = self.always + list(cand.columns)
        trainable = trainable_groups(sums, self.sel.plan)
        beta = solve(sums, sums.index(names), trainable, ridge, self.sel.tau)
        return dict(zip(names, (float(b) for b in beta)))

    def _trials(self, fwd: ForwardResult, stab: Stability, test: Sequence[Unit]) -> list[EffectTrial]:
        out = []
        last: dict[str, tuple[int, GainTest]] = {}
        for rnd, tests in enumerate(fwd.tests, start=1):
            for name, t in tests.items():
                last[name] = (rnd, t)
        for name, t in fwd.final_tests.items():
            last[name] = (last.get(name, (len(fwd.tests), t))[0], t)
        for cand in self.candidates:
            alone = fwd.tests[0].get(cand.name) if fwd.tests else None
            rnd, t_last = last.get(cand.name, (0, None))
            selected = cand.name in fwd.chosen
            prob = stab.probability.get(cand.name, 0.0)
            shared = self.represented.get(cand.name, prob)
            reason = _reason(cand, selected, t_last, fwd.dropped.get(cand.name), prob, shared, stab.threshold,
                             eligible=cand.name in self.eligible)  # fmt: skip
            reason += _rival_note(cand.name, fwd.rivals)
            test_err = None
            if test and cand.columns:
                test_err = errors(test, self.model_with(self._solo(cand), [cand.name]))
            shape = cand.shape_fit.prior_report() if cand.shape_fit is not None else {}
            out.append(EffectTrial(cand.name, cand.effect.full_params(), rnd, test_err, alone, t_last, prob,
                                   selected, reason, shape, shared))  # fmt: skip
        return out


def _rival_note(name: str, rivals: Mapping[str, Mapping[str, GainTest]]) -> str:
    """The indistinguishable rivals of a kept effect, or the kept effect a rival could not be told from."""
    notes = []
    for n, t in rivals.get(name, {}).items():
        notes.append(f"; not shown better than {n} on these flights (head-to-head gain {t.mean:+.3g} +- {t.se:.2g}, "
                     f"needs > {t.z:.2f} SE): fly more varied flights to tell them apart")  # fmt: skip
    for kept, r in rivals.items():
        if name in r:
            notes.append(f"; the flights cannot tell it from the kept {kept} (its head-to-head gain over this one "
                         f"{r[name].mean:+.3g} +- {r[name].se:.2g})")  # fmt: skip
    return "".join(notes)


def _reason(
    cand: EffectCandidate,
    selected: bool,
    t: GainTest | None,
    dropped: GainTest | None,
    prob: float,
    shared: float,
    threshold: float,
    *,
    eligible: bool,
) -> str:
    if not cand.columns:
        return f"rejected: {cand.note}"
    stab = f"chosen in {prob:.0%} of half-samples of the flights (needs more than {threshold:.0%})"
    if shared > prob:
        stab = (f"chosen, or an effect standing for it, in {shared:.0%} of half-samples of the flights (itself in "
                f"{prob:.0%}; needs more than {threshold:.0%})")  # fmt: skip
    if t is None:
        return f"not tested (the forward pass stopped at {MAX_EFFECTS} effects); {stab}"
    gain = (f"held-out gain {t.mean:+.3g} +- {t.se:.2g} (error removed per unit of change on held-out flights, {t.n_groups} flights, {t.share:.1%} of their error; "
            f"needs > {t.z:.2f} SE)")  # fmt: skip
    if selected:
        return f"kept: {gain}; {stab}"
    if dropped is not None:
        return f"dropped: redundant given the others ({gain})"
    if t.too_large:
        return (f"rejected: {gain}: R exceeds 1 by more than {t.z:.2f} SE (fitted on every channel, judged on F_z "
                f"and yaw: those hold more of its shape than its fit gives them, something else; "
                f"proxplan.identify.heldout_select.ratio_test); {stab}")  # fmt: skip
    if not t.passed:
        return f"rejected: {gain} does not hold; {stab}"
    if not eligible and shared > threshold:
        return (f"rejected: not stable on its own ({stab}); an effect standing for it is, and carries its signal "
                f"({gain})")  # fmt: skip
    if not eligible:
        return f"rejected: not stable: {stab} ({gain})"
    return f"not kept: another candidate gained more ({gain}; {stab})"
