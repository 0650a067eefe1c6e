"""Stability selection over half-samples of the flights (issue 35).

Complementary pairs of half-samples of the flights (Shah & Samworth
2013); on each half the candidates are chosen by forward selection with the Bayesian information criterion
on that half's effective samples (:func:`bic_forward`). A candidate's inclusion probability is the share of
halves that choose it; it must be chosen in MOST of them (more than :data:`PI_MIN`). The report gives
Meinshausen & Buehlmann's bound on the expected number of false selections at that threshold,
E[V] <= q^2 / ((2 pi - 1) p) (q the mean number chosen per half, p the candidates), for the record.

"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from proxplan.identify.crossval import GroupPlan, GroupSums, Ridge, group_weights, solve
from proxplan.identify.heldout_select import Candidate

N_PAIRS = 25
"""Complementary pairs of half-samples of the flights (at most 50 halves)."""
FOLD_PAIRS = 5
"""Complementary pairs of half-samples of the OTHER flights per held-out flight (:func:`fold_half_samples`): the
in-fold stability only decides whether a candidate would have been tested at all without that flight (a
yes/no per flight, not a probability that is reported), so fewer halves serve; 5 pairs keep its cost near
the main stability's on a manifest of 25 flights."""
PI_MIN = 0.5
"""A kept candidate is chosen in more than this share of the half-samples ("most resamples"), -."""


def _in_sample_sse(sums: GroupSums, cols: np.ndarray, train: np.ndarray, ridge: Ridge, tau: float) -> float:
    beta = solve(sums, cols, train, ridge, tau)
    train = sums.cells(train)
    G = np.tensordot(train, sums.G[:, cols][:, :, cols], axes=1)
    b = np.tensordot(train, sums.b[:, cols], axes=1)
    c = float(train @ sums.c)
    return max(c - 2.0 * beta @ b + beta @ G @ beta, 1e-300)


def bic_forward(
    sums: GroupSums,
    always: Sequence[str],
    candidates: Sequence[Candidate],
    train: np.ndarray,
    ridge: Ridge,
    tau: float,
    *,
    max_terms: int,
) -> list[str]:
    """Forward selection by BIC on the groups weighted by ``train`` (K,): add the candidate that lowers
    n ln(SSE) + k ln(n) most (n = effective samples, weight / tau; k = coefficients), while it does.
    Returns the chosen candidates' names in order."""
    n_eff = max(float(train @ group_weights(sums)) / tau, 2.0)
    chosen: list[Candidate] = []
    cols_of = {c.name: sums.index(c.columns) for c in candidates}
    base = sums.index(always) if always else np.zeros(0, dtype=int)
    current = n_eff * np.log(_in_sample_sse(sums, base, train, ridge, tau) / n_eff)
    while len(chosen) < max_terms:
        active = np.concatenate([base] + [cols_of[c.name] for c in chosen]) if chosen else base
        best, best_score, best_fit = None, current, current
        for cand in candidates:
            if cand in chosen:
                continue
            sse = _in_sample_sse(sums, np.concatenate([active, cols_of[cand.name]]), train, ridge, tau)
            fit = n_eff * np.log(sse / n_eff)
            score = fit + len(cand.columns) * np.log(n_eff)
            if score < best_score:
                best, best_score, best_fit = cand, score, fit
        if best is None:
            break
        chosen.append(best)
        current = best_fit
    return [c.name for c in chosen]


@dataclass(frozen=True)
class Stability:
    """Inclusion probability of each candidate over the halves, the threshold it must exceed, the mean
    number chosen per half, the halves, and the candidates (for Meinshausen & Buehlmann's bound)."""

    probability: dict[str, float]
    threshold: float
    mean_chosen: float
    n_halves: int
    n_candidates: int = 0
    picks: tuple[tuple[str, ...], ...] = ()  # per half used, the candidates it chose (in order)

    def stable(self, name: str) -> bool:
        return self.probability.get(name, 0.0) > self.threshold

    @property
    def expected_false_bound(self) -> float | None:
        """Meinshausen & Buehlmann's bound on the expected false selections, q^2 / ((2 pi - 1) p), at the
        smallest inclusion probability that passes (a share of the halves just above the threshold)."""
        if self.n_candidates <= 0 or self.n_halves <= 0:
            return None
        pi = (np.floor(self.threshold * self.n_halves) + 1) / self.n_halves
        return float(self.mean_chosen**2 / ((2.0 * pi - 1.0) * self.n_candidates)) if pi > 0.5 else None


def half_samples(plan: GroupPlan, seed: int, n_pairs: int = N_PAIRS) -> list[np.ndarray]:
    """Complementary pairs of half-samples of the train clusters (flights), as 0/1 weights per group ((G,)
    each): every distinct split of the train clusters into two halves when there are at most
    ``n_pairs`` of them (few flights: the exact distribution, each split once), else ``n_pairs``
    random splits from ``seed``."""
    from itertools import combinations
    from math import comb

    train_clusters = np.unique(plan.cluster[~plan.held_out_only])
    cut = len(train_clusters) // 2
    if cut == 0:
        return []
    n_splits = comb(len(train_clusters), cut) // (2 if 2 * cut == len(train_clusters) else 1)
    if n_splits <= n_pairs:
        firsts = [np.array(c) for c in combinations(train_clusters, cut)][:n_splits]
    else:
        rng = np.random.default_rng(seed)
        firsts = [rng.permutation(train_clusters)[:cut] for _ in range(n_pairs)]
    halves = []
    for first in firsts:
        for part in (first, np.setdiff1d(train_clusters, first)):
            halves.append((np.isin(plan.cluster, part) & ~plan.held_out_only).astype(float))
    return halves


def fold_half_samples(plan: GroupPlan, seed: int) -> dict[int, list[np.ndarray]]:
    """For each train cluster (flight) c: complementary half-samples (:func:`half_samples`, at most
    :data:`FOLD_PAIRS` pairs) of the OTHER train clusters, what stability selection would have seen had c been
    held out (:func:`fold_eligibility`)."""
    train_clusters = np.unique(plan.cluster[~plan.held_out_only])
    out = {}
    for c in train_clusters:
        without = replace(plan, held_out_only=plan.held_out_only | (plan.cluster == c))
        out[int(c)] = half_samples(without, seed, n_pairs=FOLD_PAIRS)
    return out


def fold_eligibility(
    plan: GroupPlan, eligible_without: dict[int, set[str]], names: Sequence[str]
) -> dict[str, np.ndarray]:
    """name -> (G,) bool: whether the candidate would have been eligible (stable) had each group's cluster
    been held out (``eligible_without``: train cluster -> the names stable on the other train clusters). A
    group of a cluster that is never fitted (a validation flight) is held out from every fit: there the
    selection on all train flights is the in-fold one (True for every name given).

    Why: the gain test predicts each flight by a fit that did not see it, but the candidates it tests were
    CHOSEN (stability selection) on every flight, that one included; a term that fits one flight's noise is
    then tested where it was picked, and the test is anti-conservative. With this mask the gain of a flight is
    that of the whole procedure run without it: where the candidate would not have been chosen, it adds
    nothing there (gain 0; cross-validation of the selection step, Hastie, Tibshirani & Friedman, ESL 7.10.2)."""
    out = {}
    for name in names:
        mask = np.ones(plan.n_groups, dtype=bool)
        for c, stable in eligible_without.items():
            if name not in stable:
                mask[plan.cluster == c] = False
        out[name] = mask
    return out


def stability(
    sums: GroupSums,
    always: Sequence[str],
    candidates: Sequence[Candidate],
    plan: GroupPlan,
    ridge: Ridge,
    tau: float,
    *,
    max_terms: int,
    seed: int = 0,
    halves: Sequence[np.ndarray] | None = None,
) -> Stability:
    """Inclusion probabilities of ``candidates`` over complementary half-samples of the train groups
    (module docstring), each half choosing by :func:`bic_forward`."""
    halves = list(halves) if halves is not None else half_samples(plan, seed)
    counts = dict.fromkeys((c.name for c in candidates), 0)
    picks = []
    for w in halves:
        if not np.any(w * group_weights(sums) > 0):
            continue
        picks.append(tuple(bic_forward(sums, always, candidates, w, ridge, tau, max_terms=max_terms)))
        for name in picks[-1]:
            counts[name] += 1
    used = len(picks)
    prob = {k: v / used if used else 0.0 for k, v in counts.items()}
    q = sum(map(len, picks)) / used if used else 0.0
    return Stability(prob, PI_MIN, q, used, len(candidates), tuple(picks))
