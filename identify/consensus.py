"""What the half-samples of a discovery search picked, and which terms that search tests (issue 35).

Discovery (:mod:`proxplan.identify.discovery`) runs a sparse regression on each half-sample of the train
flights. Its picks are tallied here, per term key (``"<channel>*<feature>"``,
:func:`proxplan.physics.term_key`), per group of near-duplicates (:func:`proxplan.physics.feature_group`)
and per half; :meth:`PickTally.tested` then names the terms the held-out test tries. The SAME tally and
rule serve the search on all train flights and the search each held-out flight's fold would have run
(:meth:`PickTally.eligible`, :func:`proxplan.identify.stability.fold_eligibility`), so the cross-validation
of the selection step judges the rule that is applied, member by member.

The rule (Meinshausen & Buehlmann 2010, stability selection, applied to a term and the terms that stand
for it, not to a label):
- a group is stable when more than :data:`proxplan.identify.stability.PI_MIN` of the halves picked any of
  its members;
- a pick STANDS FOR a term when it shares more than :data:`REPRESENTS_R2` of the term's variance
  (:func:`stands_for`);
- tested: the members of stable groups that most halves' picks stand for; in a stable group none of whose
  members is, the one member standing for the most picks, the halves' consensus (:func:`tested_members`).

The named library effects follow the same rule (:func:`sets_standing_for`, :func:`represented_shares`,
:func:`split_vote_eligible`): an effect may be kept when more than half of the halves picked it, or picked it
or an effect standing for it while none of those is stable on its own (a split vote); each is its own
hypothesis in the Bonferroni count (distinct mechanisms, not copies of one feature).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from proxplan.identify.crossval import GroupSums
from proxplan.identify.stability import PI_MIN, Stability
from proxplan.physics import feature_group, parse_term_key, term_key

REPRESENTS_R2 = 0.5
"""A feature a half-sample picked stands for a term when it shares more than this share of the term's variance
(squared cosine of their residualized, weighted columns: the R^2 of regressing one on the other), -. "More
than half", as in "chosen in most halves" (:data:`proxplan.identify.stability.PI_MIN`): near-duplicates (a lag
and its neighbour, a kernel at the next width) share most of their variance and stand for each other; two
members of one group that describe different signals do not."""


def group_of(key: str) -> str:
    """``"<channel>|<group>"`` of a term key (:func:`proxplan.physics.feature_terms.term_key`)."""
    channel, feature = parse_term_key(key)
    return f"{channel}|{feature_group(feature)}"


def stands_for(sums: GroupSums, weights: np.ndarray, names: Sequence[str]) -> np.ndarray:
    """(F, F) bool, symmetric: whether column ``names[j]`` of ``sums`` stands for ``names[k]``
    (:data:`REPRESENTS_R2`), their Gram taken over the groups weighted by ``weights`` (G,): the squared
    cosine of the two columns (:func:`sets_standing_for` with one column each and nothing residualized)."""
    return sets_standing_for(sums, weights, [], [(n,) for n in names])


def sets_standing_for(
    sums: GroupSums, weights: np.ndarray, always: Sequence[str], sets: Sequence[Sequence[str]]
) -> np.ndarray:
    """(E, E) bool, symmetric: whether candidate ``sets[j]`` (a library effect's columns of ``sums``) stands for
    ``sets[k]``: the largest squared canonical correlation of their columns, each residualized on the
    ``always`` columns (the tangents fitted beside every candidate), exceeds :data:`REPRESENTS_R2`; the Gram over
    the groups weighted by ``weights`` (G,), each over its channel cells. For one column each it is the
    squared cosine of the residualized columns; for an effect with several linear parameters (``own_velocity``)
    it is the share of one's variance the other explains in its best direction."""
    if not sets:
        return np.zeros((0, 0), dtype=bool)
    names = [c for cols in sets for c in cols]
    idx = sums.index(list(always) + names)
    gram = np.tensordot(sums.cells(weights), sums.G[:, idx][:, :, idx], axes=1)
    a = len(always)
    part = gram[a:, a:]
    if a:
        part = part - gram[a:, :a] @ np.linalg.pinv(gram[:a, :a], rcond=1e-12, hermitian=True) @ gram[:a, a:]
    if all(len(cols) == 1 for cols in sets):  # one column each: the squared cosine, all pairs at once
        d = np.sqrt(np.clip(np.diag(part), 1e-300, None))
        return (part / np.outer(d, d)) ** 2 > REPRESENTS_R2
    ends = np.cumsum([0] + [len(cols) for cols in sets])
    blocks = [slice(int(ends[k]), int(ends[k + 1])) for k in range(len(sets))]
    out = np.zeros((len(sets), len(sets)), dtype=bool)
    for j, bj in enumerate(blocks):
        for k, bk in enumerate(blocks):
            if j == k:
                out[j, k] = True
            elif k > j:
                inv_j = np.linalg.pinv(part[bj, bj], rcond=1e-12, hermitian=True)
                inv_k = np.linalg.pinv(part[bk, bk], rcond=1e-12, hermitian=True)
                rho2 = np.linalg.eigvals(inv_j @ part[bj, bk] @ inv_k @ part[bk, bj]).real
                out[j, k] = out[k, j] = bool(rho2.size and rho2.max() > REPRESENTS_R2)
    return out


def represented_shares(stab: Stability, names: Sequence[str], stands: np.ndarray) -> dict[str, float]:
    """For each of ``names`` (library effects, ``stands`` (E, E) from :func:`sets_standing_for`), the share of
    ``stab``'s halves that picked it or an effect standing for it: the rule of :func:`represented_counts`
    for the named effects. Two effects that describe nearly the same signal (a jet hitting the floor and the
    floor's stagnation under it) split a real effect's picks between them, neither in most halves."""
    return {k: v / max(stab.n_halves, 1) for k, v in _counts(stands, names, stab.picks).items()}


def split_vote_eligible(
    stab: Stability, names: Sequence[str], stands: np.ndarray, represented: dict[str, float]
) -> set[str]:
    """The effects of ``names`` the held-out test may keep: those most halves picked (``stab``), and those
    most halves picked or an effect standing for them (``represented``, :func:`represented_shares`) when
    NONE of the effects standing for them is stable on its own: a vote split between near-copies, neither
    picked in most halves. A signal a stable effect already carries is tested through that effect: an
    effect that merely lies in its span (``climb_inflow``'s v_z column inside ``own_velocity``'s three) would
    otherwise enter the Bonferroni count and cost the stable one its test."""
    out = set()
    for k, name in enumerate(names):
        if stab.stable(name):
            out.add(name)
        elif represented.get(name, 0.0) > stab.threshold:
            if not any(stab.stable(names[int(j)]) for j in np.flatnonzero(stands[k]) if int(j) != k):
                out.add(name)
    return out


def represented_counts(sums: GroupSums, weights: np.ndarray, picks: Sequence[Sequence[str]]) -> dict[str, int]:
    """For every feature picked in any half (``picks``: per half, the names of ``sums``' columns it picked), the
    number of halves that picked it or a feature standing for it (:func:`stands_for`, the Gram over the
    groups weighted by ``weights`` (G,), the train flights).

    Why: stability is judged per GROUP of near-duplicates (a per-feature count would split a real effect's
    picks between its copies), and the held-out test then tries the group's members the halves picked. A group
    is one hypothesis only while its picks describe one signal: when the halves agree on a group but each
    picks a different, unrelated member, no member was chosen in most resamples, and the best of them on all
    flights is a pick among many."""
    names = sorted({f for picked in picks for f in picked})
    return _counts(stands_for(sums, weights, names), names, picks)


def _counts(stands: np.ndarray, names: Sequence[str], picks: Sequence[Sequence[str]]) -> dict[str, int]:
    pos = {f: k for k, f in enumerate(names)}
    counts = dict.fromkeys(names, 0)
    for picked in picks:
        if picked:
            hit = np.any(stands[:, [pos[f] for f in picked]], axis=1)
            for k in np.flatnonzero(hit):
                counts[names[int(k)]] += 1
    return counts


def tested_members(member_prob: dict[str, float], represented_prob: dict[str, float], stab: Stability) -> list[str]:
    """The members of the stable groups the held-out test tries (most often picked first): those that most halves'
    picks stand for (``represented_prob`` above the stability threshold); in a stable group none of whose members
    is, the one member standing for the most picks (ties: the most often picked itself, then the name), the
    halves' consensus for that group. One hypothesis per stable group is then tested, never the best of its
    members on all flights (:func:`represented_counts`)."""
    order = sorted(member_prob, key=lambda k: (-member_prob[k], k))
    kept = [k for k in order if stab.stable(group_of(k)) and represented_prob.get(k, 0.0) > stab.threshold]
    covered = {group_of(k) for k in kept}
    for k in sorted(order, key=lambda k: (-represented_prob.get(k, 0.0), -member_prob[k], k)):
        group = group_of(k)
        if stab.stable(group) and group not in covered:
            kept.append(k)
            covered.add(group)
    return sorted(kept, key=lambda k: (-member_prob[k], k))


@dataclass
class PickTally:
    """What one set of ``n_halves`` half-samples picked, over every channel searched: per term key the halves
    that picked it (``member``) and that picked it or a term standing for it (``represented``), per group
    (``"<channel>|<group>"``) the halves that picked any member, per half the groups it picked, and per term
    key the keys that stand for it (``similar``, the key itself included)."""

    n_halves: int
    member: dict[str, int] = field(default_factory=dict)
    represented: dict[str, int] = field(default_factory=dict)
    group: dict[str, int] = field(default_factory=dict)
    groups_per_half: np.ndarray = field(init=False)
    similar: dict[str, set[str]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.groups_per_half = np.zeros(self.n_halves)

    def add(self, channel: str, picks: Sequence[Sequence[str]], names: Sequence[str], stands: np.ndarray) -> None:
        """Tally one channel's ``picks`` (per half, the features picked); ``stands`` (F, F) is
        :func:`stands_for` over ``names``, which hold every picked feature."""
        for h, picked in enumerate(picks):
            groups = {f"{channel}|{feature_group(f)}" for f in picked}
            self.groups_per_half[h] += len(groups)
            for g in groups:
                self.group[g] = self.group.get(g, 0) + 1
            for f in picked:
                self.member[term_key(channel, f)] = self.member.get(term_key(channel, f), 0) + 1
        for f, count in _counts(stands, names, picks).items():
            if count:
                self.represented[term_key(channel, f)] = count
        for k, f in enumerate(names):
            self.similar[term_key(channel, f)] = {term_key(channel, names[int(j)]) for j in np.flatnonzero(stands[k])}

    def probabilities(self, counts: dict[str, int]) -> dict[str, float]:
        """``counts`` as shares of the halves."""
        return {k: v / max(self.n_halves, 1) for k, v in counts.items()}

    def stability(self, n_groups: int) -> Stability:
        """The groups' inclusion probabilities, at :data:`PI_MIN`, over ``n_groups`` groups searched."""
        q = float(self.groups_per_half.mean()) if self.n_halves else 0.0
        return Stability(self.probabilities(self.group), PI_MIN, q, self.n_halves, n_groups)

    def tested(self, n_groups: int) -> list[str]:
        """The term keys this search tests (:func:`tested_members`)."""
        return tested_members(
            self.probabilities(self.member), self.probabilities(self.represented), self.stability(n_groups)
        )

    def eligible(self, keys: Sequence[str], n_groups: int) -> set[str]:
        """Those of ``keys`` this search would have tested, itself or through a tested term standing for it
        (the same hypothesis: it shares more than half of the key's variance)."""
        tested = set(self.tested(n_groups))
        return {k for k in keys if k in tested or tested & self.similar.get(k, set())}
