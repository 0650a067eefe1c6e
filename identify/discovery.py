"""Terms no library effect names: an ensemble sparse regression over declared feature families (issue 35).

After the library effects (:mod:`proxplan.identify.effect_selection`), the residual of the reference
model is searched for a term nobody listed. Candidates are the features of
:mod:`proxplan.physics.features`, from declared families (:data:`proxplan.physics.FEATURE_FAMILIES`:
temporal filter banks of every neighbour's predicted disturbance and relative state; spatial kernels
of every neighbour above, beside and below; the vehicle's own velocity; a multiplicative thrust loss;
place in the room), each on one wrench channel (F_z and the three torques): a term is
``coefficient x feature`` on that channel.

1. **Ensemble** (stability selection). On each half-sample of the flights of
   :func:`proxplan.identify.stability.half_samples`, per channel, the always-fitted columns (the vehicle
   parameters' tangents and the kept library effects) are projected out and scikit-learn's
   ``orthogonal_mp_gram`` (Orthogonal Matching Pursuit on the Gram matrix) runs its path up to
   :attr:`DiscoveryOptions.max_terms_per_channel` terms; the Bayesian information criterion on the
   half's effective samples (weight / tau) picks how many. Stability is judged per GROUP of
   near-duplicate features (:func:`proxplan.physics.features.feature_group`: a neighbour's kernels at
   several widths, a kernel and its lagged copies) on each channel: a group's **inclusion probability**
   is the share of halves that pick any of its members, and it must be picked in most of them
   (:data:`proxplan.identify.stability.PI_MIN`). Among
   near-duplicates the halves split their picks, so a per-feature count would under-rate a real effect;
   which member describes it best is the held-out test's to say.
2. **Held out.** The members of a stable group that most halves' picks STAND FOR (a pick sharing more than
   half of a member's variance stands for it), or, where none is, the one member standing for the most
   picks (:mod:`proxplan.identify.consensus`; never the best of the group's members on all flights, which
   would be a pick among many), enter the joint design beside the tangents and the kept effects (members of
   one group are one hypothesis: the Bonferroni count is the stable groups'). The same search and the same
   rule are run as if each train flight had been held out, and a term's gain on a flight counts only where
   that in-fold search would have tested it or a term standing for it
   (:meth:`proxplan.identify.consensus.PickTally.eligible`,
   :func:`proxplan.identify.stability.fold_eligibility`); the greedy held-out gain test
   (:func:`proxplan.identify.crossval.heldout_forward`: every flight predicted
   by a fit without it; Bonferroni over the round) keeps them, and a backward pass drops any that no
   longer pass given the others.

No threshold here is set on data: the test level (:data:`proxplan.identify.crossval.ALPHA`), the
stability bound and the BIC are derived (docs/identify.md). The kept terms of all channels form ONE
effect ``Effect("discovered:residual", {key: coefficient})``, the key ``"<channel>*<feature>"`` for a feature that
is already a force or torque (coefficient per feature unit) and ``"<channel>*W*<feature>"`` for a shape
(a kernel, a speed), scaled to the target: times its weight W for a force, W L for a torque
(:func:`proxplan.physics.feature_terms.term_scale`; one coefficient serves a 32 g and a 650 g vehicle), applied by :mod:`proxplan.physics.effects` like any effect and saved with the model.
"""

from __future__ import annotations

import warnings
from collections.abc import Collection, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from sklearn import config_context
from sklearn.linear_model import orthogonal_mp_gram

from proxplan.identify.consensus import PickTally, group_of, stands_for
from proxplan.identify.crossval import GroupSums, solve, trainable_groups
from proxplan.identify.design import CHANNELS, SelectionSet
from proxplan.identify.heldout_select import Candidate, ForwardResult, heldout_forward
from proxplan.identify.lever_form import lever_forms
from proxplan.identify.refine import Refined, refine_scaled_terms, term_column
from proxplan.identify.sampled import sampled_features, unit_parts
from proxplan.identify.stability import Stability, fold_eligibility, fold_half_samples, half_samples
from proxplan.identify.type_split import TypeSplit, split_candidates, split_name
from proxplan.physics import (
    DISCOVERED_PREFIX,
    FEATURE_FAMILIES,
    FEATURE_NAMES,
    feature_family,
    feature_group,
    is_wrench_feature,
    parse_term_key,
    term_formula,
    term_type,
    untyped_key,
)

DISCOVERED_NAME = f"{DISCOVERED_PREFIX}residual"
"""Name of the one effect holding every kept term."""


@dataclass(frozen=True)
class DiscoveryOptions:
    """What is searched and how many terms a half-sample's path may take."""

    channels: tuple[str, ...] = CHANNELS
    # declared families searched (proxplan.physics.FEATURE_FAMILIES); the constant ("bias") is thrust_bias's
    families: tuple[str, ...] = tuple(f for f in FEATURE_FAMILIES if f != "bias")
    max_terms_per_channel: int = 4  # OMP path length per channel and half-sample
    max_terms: int = 8  # at most this many terms kept in all


@dataclass(frozen=True)
class Term:
    """One candidate term: a feature on a channel."""

    channel: str
    feature: str

    @property
    def key(self) -> str:
        return f"{self.channel}*{self.feature}"


@dataclass
class DiscoveryResult:
    """Every term that was stable enough to be tested, with its inclusion probability and held-out
    gain, the kept ones' coefficients (channel unit per feature unit), and the stability record."""

    kept: dict[str, float]  # "<channel>*<feature>" -> coefficient
    coefficients: dict[str, float]  # every column of the final joint fit (always-fitted ones + kept terms)
    stability: Stability
    forward: ForwardResult
    columns: dict[str, np.ndarray] = field(default_factory=dict)  # term key -> (N, 4) column, noise units
    top: list[tuple[str, float]] = field(default_factory=list)  # the most often picked terms (key, probability)
    member_probability: dict[str, float] = field(default_factory=dict)  # term key -> share of halves picking it
    # term key -> (G,) bool: would the search without that group's flight have tested it (stability.fold_eligibility)
    fold_eligible: dict[str, np.ndarray] = field(default_factory=dict)
    # term key -> share of halves whose picks stand for it (a pick sharing more than half its variance)
    represented_probability: dict[str, float] = field(default_factory=dict)
    # kept terms whose scales were searched off the grid (a kernel's width and decay length, a time copy's delay or
    # time constant; identify.refine; the accepted ones stand in ``kept`` under their refined keys)
    refined: list[Refined] = field(default_factory=list)
    # candidate terms also offered with one coefficient per target type (identify.type_split); a kept one stands in
    # ``kept`` as its per-type keys "<key>@<type>"
    splits: list[TypeSplit] = field(default_factory=list)
    # each kept term as the candidate it was kept as (a term key, or a split's name) -> its keys in ``kept``
    groups: dict[str, tuple[str, ...]] = field(default_factory=dict)
    # a stable term's lever form (identify.lever_form) -> the stable term it is a form of
    lever_of: dict[str, str] = field(default_factory=dict)

    def _grid(self, key: str) -> str:
        """Term ``key``'s grid term where it was refined (of merged siblings, the first kept), else itself."""
        return next((r.origin for r in self.refined if r.key == key and r.accepted), key)

    def origin(self, key: str) -> str:
        """The term key ``key`` was picked as: its grid term (:meth:`_grid`); a per-type term's, the term with one
        coefficient."""
        return untyped_key(self._grid(key))

    def tested_as(self, key: str) -> str:
        """The candidate the forward pass tested term ``key`` as: a per-type key's split, else its origin."""
        origin = self.origin(key)
        return split_name(origin) if term_type(key) is not None else origin

    def keys_of(self, names: Collection[str]) -> set[str]:
        """The term keys of the kept candidates ``names`` (:attr:`groups`)."""
        return {k for n, keys in self.groups.items() if n in names for k in keys}

    def split_record(self, key: str) -> dict[str, Any] | None:
        """How term ``key``'s two forms (one coefficient, one per target type) fared in the forward pass: the
        types, the form kept, and each form's test in the last round that tested both (None: not offered)."""
        origin = self.origin(key)
        split = next((sp for sp in self.splits if sp.key == origin), None)
        if split is None:
            return None
        both = [t for t in self.forward.tests if origin in t and split.name in t]
        return {"types": list(split.types), "form": "per target type" if term_type(key) else "one coefficient",
                "test_one_coefficient": both[-1][origin].to_json() if both else None,
                "test_per_type": both[-1][split.name].to_json() if both else None}  # fmt: skip

    def replaced(self) -> set[str]:
        """The grid terms an accepted refinement stands for."""
        return {k for r in self.refined if r.accepted for k in r.replaces}

    def refinements(self, key: str) -> tuple[Refined | None, Refined | None]:
        """(the refinement reported for term ``key``: the accepted one it is, else the last search of it; the
        search of its siblings as one term, where that was not accepted and is not the first)."""
        of = [r for r in self.refined if key == r.key and r.accepted] or [r for r in self.refined if key in r.replaces]
        shown = of[-1] if of else None
        sibling = next((r for r in self.refined if r.merged and key in r.replaces and r is not shown), None)
        return shown, sibling

    def report(self) -> list[dict[str, Any]]:
        """One JSON entry per term that was picked in any half-sample (strongest first, at most 12)."""
        out = []
        last: dict[str, Any] = {}
        for tests in self.forward.tests:
            last.update(tests)
        last.update(self.forward.final_tests)
        origins = {self.origin(k) for k in self.kept} | self.replaced()
        keys = list(self.kept) + [k for k, _ in self.top if k not in self.kept and k not in origins]
        for key in keys[:12]:
            channel, feature = parse_term_key(key)
            origin = self.origin(key)
            t = last.get(self.tested_as(key))
            selected = key in self.kept
            group = group_of(key)
            prob = self.member_probability.get(self.lever_of.get(origin, origin), 0.0)
            shown, sibling = self.refinements(key)
            refined = None if shown is None else shown.to_json()
            out.append({
                "name": DISCOVERED_NAME, "channel": channel, "feature": feature, "family": feature_family(feature),
                "formula": term_formula({key: self.kept[key]}) if selected else "", "features": [feature],
                "params": {key: self.kept[key]} if selected else {}, "inclusion_probability": prob,
                "represented_probability": self.represented_probability.get(self.lever_of.get(origin, origin), 0.0),
                "refined": refined, "lever_form_of": self.lever_of.get(origin),
                "sibling_merge": None if sibling is None else sibling.to_json(),
                "type_split": self.split_record(key), "target_type": term_type(key),
                "group": group, "group_inclusion_probability": self.stability.probability.get(group, 0.0),
                "stable": self.stability.stable(group), "heldout_gain": None if t is None else t.to_json(),
                "selected": selected, "rmse_fz_N": None,
            })  # fmt: skip
        return out


def _residualized(a: np.ndarray, y: np.ndarray, x: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``y`` (N,) and ``x`` (N, F) with the always-fitted columns ``a`` (N, A) projected out by a weighted
    fit on the rows of weight ``w`` (N,) (Frisch-Waugh-Lovell, once for all half-samples: what a term adds
    beyond the recalibration and the kept effects)."""
    if a.shape[1] == 0:
        return y, x
    aw = a * w[:, None]
    gram = aw.T @ a
    gram += 1e-12 * max(float(np.trace(gram)) / a.shape[1], 1e-300) * np.eye(a.shape[1])
    coef = np.linalg.lstsq(gram, aw.T @ np.column_stack([y, x]), rcond=None)[0]
    r = np.column_stack([y, x]) - a @ coef
    return r[:, 0], r[:, 1:]


WEIGHTS_PER_PRODUCT = 16
"""Half-samples whose weighted Gram matrices are formed in one matrix product (memory: this many p x p
matrices; the same sums as one at a time, up to rounding)."""


def _weighted_sums(sums: GroupSums, weights: Sequence[np.ndarray]) -> Iterator[tuple[np.ndarray, np.ndarray, float]]:
    """For each group weighting ``w`` (G,) of ``weights``: (sum_g w_g G_g (p, p), sum_g w_g b_g (p,),
    sum_g w_g c_g), formed :data:`WEIGHTS_PER_PRODUCT` at a time in one matrix product."""
    k, p = sums.G.shape[0], sums.G.shape[1]
    g_flat = sums.G.reshape(k, p * p)
    for start in range(0, len(weights), WEIGHTS_PER_PRODUCT):
        w = np.array(weights[start : start + WEIGHTS_PER_PRODUCT], dtype=float)
        gp, bp, cp = (w @ g_flat).reshape(-1, p, p), w @ sums.b, w @ sums.c
        for j in range(w.shape[0]):
            yield gp[j], bp[j], float(cp[j])


def omp_bic(Gp: np.ndarray, bp: np.ndarray, cp: float, weight: float, n_eff: float, max_terms: int) -> list[int]:
    """Indices of the columns an OMP path picks on one half-sample's weighted sums (Gram ``Gp`` (p, p),
    ``bp`` (p,), ``cp``, their total ``weight``), the path's length chosen by BIC (module docstring)."""
    d = np.sqrt(np.clip(np.diag(Gp), 0.0, None))
    ok = np.flatnonzero(d > 1e-9 * max(float(d.max()) if d.size else 0.0, 1e-300))
    if ok.size == 0 or cp <= 0.0:
        return []
    Gn = Gp[np.ix_(ok, ok)] / np.outer(d[ok], d[ok])
    bn = bp[ok] / d[ok]
    k_max = min(max_terms, ok.size)
    with warnings.catch_warnings(), config_context(skip_parameter_validation=True):  # collinear features end
        warnings.simplefilter("ignore")  # the path early; the arguments are ours (validation costs ~10 ms a call)
        path = orthogonal_mp_gram(Gn, bn, n_nonzero_coefs=k_max, return_path=True)
    path = path.reshape(ok.size, -1)
    best_score, best_sel = n_eff * np.log(max(cp, 1e-300) / weight), []
    for k in range(path.shape[1]):
        beta = path[:, k]
        nz = np.flatnonzero(beta)
        sse = max(cp - 2.0 * beta @ bn + beta @ Gn @ beta, 1e-300)
        score = n_eff * np.log(sse / weight) + len(nz) * np.log(n_eff)
        if score < best_score:
            best_score, best_sel = score, [int(ok[j]) for j in nz]
    return best_sel


def discover_terms(
    sel: SelectionSet,
    always: dict[str, np.ndarray],
    ridge_of,
    *,
    options: DiscoveryOptions = DiscoveryOptions(),
    seed: int = 0,
) -> DiscoveryResult:
    """Search every channel of ``options.channels`` for terms the model lacks (module docstring).

    ``always`` are the always-fitted columns (name -> (N, 4), noise units: tangents and kept effects);
    ``ridge_of(names)`` gives their priors over a column list (:func:`proxplan.identify.design.tangent_ridge`)."""
    feat_idx = np.array([k for k, f in enumerate(FEATURE_NAMES) if feature_family(f) in options.families])
    names = [FEATURE_NAMES[k] for k in feat_idx]
    parts = unit_parts(sel)
    x = sampled_features(sel, names, parts)
    y = sel.residual
    halves = half_samples(sel.plan, seed)
    folds = fold_half_samples(sel.plan, seed)  # the same search as if each train flight had been held out
    tally = PickTally(len(halves))
    fold_tally = {cl: PickTally(len(fold_halves)) for cl, fold_halves in folds.items()}
    always_names = list(always)
    groups_seen: set[str] = set()
    wrench_feature = np.array([is_wrench_feature(n) for n in names])
    train = ~sel.plan.held_out_only
    train_rows = train[sel.group]
    for channel in options.channels:
        c = CHANNELS.index(channel)
        xc = np.where(wrench_feature, x, x * sel.target_scale(channel)[:, None]) / sel.row_scale[:, c : c + 1]
        usable = np.flatnonzero(np.any(xc != 0.0, axis=0) & np.all(np.isfinite(xc), axis=0))
        groups_seen |= {f"{channel}|{feature_group(names[j])}" for j in usable}
        a = np.column_stack([always[k][:, c] for k in always_names]) if always_names else np.zeros((len(y), 0))
        yr, xr = _residualized(a, y[:, c], xc[:, usable], sel.weight * train_rows)
        sums = GroupSums.build(xr, yr, sel.weight, sel.group, sel.plan.n_groups, [names[j] for j in usable])
        columns_here = [names[j] for j in usable]
        picks = list(_picks(sums, halves, sel.tau, options.max_terms_per_channel, columns_here))
        fold_picks = {
            cl: list(_picks(sums, fold_halves, sel.tau, options.max_terms_per_channel, columns_here))
            for cl, fold_halves in folds.items()
        }
        picked = sorted({f for ps in [picks, *fold_picks.values()] for p in ps for f in p})
        tally.add(channel, picks, picked, stands_for(sums, train.astype(float), picked))
        for cl, ps in fold_picks.items():  # the Gram on the train flights of that fold
            fold_tally[cl].add(channel, ps, picked, stands_for(sums, (train & (sel.plan.cluster != cl)) * 1.0, picked))
    stab = tally.stability(len(groups_seen))
    member_prob = tally.probabilities(tally.member)
    represented_prob = tally.probabilities(tally.represented)
    stable = tally.tested(len(groups_seen))
    columns: dict[str, np.ndarray] = {}
    for key in stable:
        columns[key] = term_column(sel, key, x[:, names.index(parse_term_key(key)[1])])
    levers = lever_forms(sel, stable)  # a side-axis torque term's second form: the force at its lever arm
    if levers:
        x_lever = sampled_features(sel, [parse_term_key(lk)[1] for lk in levers.values()], parts)
        for j, lk in enumerate(levers.values()):
            columns[lk] = term_column(sel, lk, x_lever[:, j])
    splits = split_candidates(sel, stable, columns)  # each term's third form: one coefficient per target type
    by_name = {sp.name: sp for sp in splits}
    for sp in splits:
        columns.update(sp.columns)
    fwd = ForwardResult()
    sums = sel.sums({**always, **columns})
    ridge = ridge_of(sums.columns)
    without = {cl: t.eligible(stable, len(groups_seen)) for cl, t in fold_tally.items()}
    fold = fold_eligibility(sel.plan, without, stable)
    fold.update({n: fold[sp.key] for sp in splits for n in (sp.name, *sp.typed)})
    fold.update({lk: fold[k] for k, lk in levers.items()})
    if stable:  # the forms of one term in this order: one coefficient, its lever form, one per target type
        alternatives = {n: sp.key for sp in splits for n in (sp.key, sp.name)} | {
            n: k for k, lk in levers.items() for n in (k, lk)}  # fmt: skip
        fwd = heldout_forward(sums, always_names, [Candidate(k, (k,)) for k in stable]
                              + [Candidate(lk, (lk,)) for lk in levers.values()]
                              + [Candidate(sp.name, sp.typed) for sp in splits], sel.plan, ridge, sel.tau,
                              max_terms=options.max_terms,
                              hypothesis={k: group_of(k) for k in stable} | {sp.name: group_of(sp.key) for sp in splits}
                              | {lk: group_of(k) for k, lk in levers.items()},
                              fold_eligible=fold, alternatives=alternatives)  # fmt: skip
    kept_keys = [k for n in fwd.chosen for k in (by_name[n].typed if n in by_name else (n,))]
    refined = refine_scaled_terms(sel, {**always, **{k: columns[k] for k in kept_keys}}, kept_keys, ridge_of, parts)
    renamed: dict[str, str] = {}
    for r in (r for r in refined if r.accepted):  # the refined term stands where its grid term(s) were tested
        columns[r.key] = r.column
        fold[r.key] = np.logical_or.reduce([fold[k] for k in r.replaces])
        renamed.update({k: r.key for k in r.replaces})
    groups: dict[str, tuple[str, ...]] = {}  # kept candidate -> its keys (a split: its per-type keys)
    for n in fwd.chosen:
        keys = tuple(dict.fromkeys(renamed.get(k, k) for k in (by_name[n].typed if n in by_name else (n,))))
        keys = tuple(k for k in keys if all(k not in g for g in groups.values()))  # merged siblings: one term
        if keys:
            groups[n if n in by_name else keys[0]] = keys
    chosen = [k for keys in groups.values() for k in keys]
    if renamed:
        sums = sel.sums({**always, **{k: columns[k] for k in chosen}})
        ridge = ridge_of(sums.columns)
    names_fit = always_names + chosen
    trainable = trainable_groups(sums, sel.plan)
    beta = solve(sums, sums.index(names_fit), trainable, ridge, sel.tau) if names_fit else np.zeros(0)
    coef = dict(zip(names_fit, (float(v) for v in beta)))
    top = sorted(member_prob.items(), key=lambda kv: -kv[1])[:12]
    return DiscoveryResult(kept={k: coef[k] for k in chosen}, coefficients=coef, stability=stab, forward=fwd,
                           columns=columns, top=top, member_probability=member_prob, fold_eligible=fold,
                           represented_probability=represented_prob, refined=refined, splits=splits,
                           groups=groups, lever_of={lk: k for k, lk in levers.items()})  # fmt: skip


def _picks(
    sums: GroupSums, weights: Sequence[np.ndarray], tau: float, max_terms: int, columns: list[str]
) -> Iterator[list[str]]:
    """For each half-sample weighting of ``weights``, the features (names of ``sums``' ``columns``) its OMP
    path picks (:func:`omp_bic`)."""
    for w, (Gp, bp, cp) in zip(weights, _weighted_sums(sums, weights)):
        total = float(w @ sums.w)
        n_eff = max(total / tau, 2.0)
        yield [columns[j] for j in omp_bic(Gp, bp, cp, max(total, 1e-300), n_eff, max_terms)]
