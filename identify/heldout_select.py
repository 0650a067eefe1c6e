"""The held-out gain test and the greedy passes built on it (issue 35): :func:`gain_test` (the error a
candidate removes on each held-out flight per unit of what it changes there, pooled, Student's t over the
flights, Bonferroni), :func:`ratio_test` (that test on per-flight sums), :func:`exposure` (where a candidate
acts; :func:`fitted_exposure`, at a fit's coefficients), :func:`heldout_forward` and :func:`heldout_backward`.
The held-out fits they compare come from :mod:`proxplan.identify.crossval`, whose docstring derives the
test.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.stats import norm
from scipy.stats import t as student_t

from proxplan.identify.crossval import (
    GroupPlan,
    GroupSums,
    HeldOutFit,
    Ridge,
    change_energy,
    heldout_fit,
    solve,
    trainable_groups,
)

ALPHA = 0.05
"""Family-wise level of the gain test: on data without any of the m candidates of a round, the
chance that one of them passes, -."""
MOST_ELSEWHERE_R = 3.0
"""The held-out ratio R above which (by more than z se) a candidate fitted on more channels than it is judged
on is rejected, -: R = 2c - 1 where c is what the judged channels hold of its shape over what its fit gives
them (:func:`ratio_test`), so R = 3 is c = 2, half of that signal something else: the majority rule of the
other 1/2s of selection (stability above 1/2, ``consensus.REPRESENTS_R2`` = 1/2). Stop 59 had R = 1 (c = 1,
the exact shape), which rejects a true effect whose channels disagree mildly: on benchmark draw 19010 a
ground_jet 0.23 s late (the drawn lag 0.231 s found) removed 97 % of the held-out error at R = 1.19 +- 0.077
and was rejected (1 + 2.35 se = 1.18)."""


@dataclass(frozen=True)
class GainTest:
    """The held-out gain of one candidate (the module docstring of :mod:`proxplan.identify.crossval` derives
    it): ``gains`` (n,) per held-out flight, the error the candidate removed per unit of what it changed
    (gain / energy, -); ``mean`` the pooled ratio R = sum gain / sum energy (-), ``se`` its standard error from
    flight to flight, ``z`` the critical multiple, ``passed`` whether R > z se; ``n_groups`` the flights it
    was judged on; ``share`` the held-out squared error it removed over those flights as a share of the error
    without it (-) and ``share_lower`` that share at R - z se (what the forward pass ranks by);
    ``effective_flights`` Kish's effective number of those flights for the energy-weighted R,
    (sum e_f)^2 / sum e_f^2 (:func:`effective_units`, -); ``too_large``: R exceeds :data:`MOST_ELSEWHERE_R` by
    more than z se, for a candidate fitted on channels it is not judged on (:func:`ratio_test`'s
    ``at_most_one``)."""

    gains: np.ndarray
    mean: float
    se: float
    z: float
    passed: bool
    n_groups: int
    share: float = 0.0
    share_lower: float = 0.0
    effective_flights: float = 0.0
    too_large: bool = False

    @property
    def t(self) -> float:
        return self.mean / self.se if self.se > 0 else (np.inf if self.mean > 0 else 0.0)

    def to_json(self) -> dict[str, float | int | bool | None]:
        return {"mean_gain": self.mean, "se": self.se, "t": float(self.t) if np.isfinite(self.t) else None,
                "z_required": self.z, "passed": self.passed, "n_groups": self.n_groups,
                "groups_improved": int(np.sum(self.gains > 0.0)), "undecided": self.undecided,
                "share_of_error": self.share, "effective_flights": self.effective_flights,
                "one_flight": self.one_flight, "too_large": self.too_large}  # fmt: skip

    @property
    def undecided(self) -> bool:
        """Every held-out group (flight) gained, yet the mean is short of z standard errors: the test had too
        few groups to decide (with n flights the multiple is Student's t with n - 1 degrees of freedom)."""
        return (not self.passed) and self.n_groups >= 2 and bool(np.all(self.gains > 0.0))

    @property
    def one_flight(self) -> bool:
        """Not kept, and what the candidate changes on the held-out flights lies mostly on ONE of them
        (``effective_flights`` < 2, less than two equal flights' worth): R is mostly that flight's ratio, and
        its standard error "from flight to flight" rests on flights that barely count, so the test cannot judge
        the candidate either way (the same reason :func:`can_be_tested` asks for two flights). Typically the
        one flight that holds the effect, held out, leaves the others unable to fit what trades with it
        (docs/identify.md, "Stop 59"). A candidate that acts on ONE held-out flight only has no test at all
        (:func:`can_be_tested`) and is reported too (stop 60: that is where a user most needs to hear which
        situation to fly again; benchmark draw 19001's side kernel, chosen in every half-sample, acted on one)."""
        return (not self.passed) and self.n_groups >= 1 and 0.0 < self.effective_flights < 2.0


def effective_units(energy: np.ndarray) -> float:
    """Kish's effective number of units of a weighted mean with weights ``energy`` (n,) >= 0,
    (sum e)^2 / sum e^2 (Kish 1965, Survey Sampling): n for equal weights, 1 when one unit carries all of it,
    0 for no weight. The ratio R of :func:`ratio_test` is the energy-weighted mean of the units' ratios."""
    e = np.asarray(energy, dtype=float)
    total, sq = float(e.sum()), float(np.sum(e * e))
    return total * total / sq if sq > 0.0 else 0.0


def critical_z(m: int, dof: int | None = None) -> float:
    """The one-sided Bonferroni multiple for m candidates tested together, -: Student's t_dof^-1(1 - ALPHA / m)
    for a standard error estimated from dof + 1 values, Phi^-1(1 - ALPHA / m) when ``dof`` is None."""
    q = 1.0 - ALPHA / max(int(m), 1)
    return float(norm.ppf(q) if dof is None else student_t.ppf(q, max(int(dof), 1)))


def can_be_tested(acts: np.ndarray, cluster: np.ndarray | None) -> bool:
    """Whether a candidate acting on the (G, C) groups and channels ``acts`` can pass the gain test at all: it
    acts on at least two held-out flights (``cluster`` (G,), each group's flight; without, two groups). On one
    flight or none there is no standard error and no test, so the candidate cannot be falsely kept, and it does
    not count in the Bonferroni m: Tarone's modified Bonferroni (Tarone 1990, Biometrics 46: 515-522) counts
    only the hypotheses whose smallest attainable p-value is below the level, and where there is no test that
    p-value is 1. Which flights a candidate acts on is decided by its fit on every train flight
    (:func:`exposure`), not by its held-out gains."""
    rows = np.flatnonzero(np.atleast_2d(acts).any(axis=1))
    units = rows if cluster is None else np.unique(np.asarray(cluster)[rows])
    return int(units.size) >= 2


def exposure(sums: GroupSums, cols: np.ndarray, beta: np.ndarray, tau: float) -> np.ndarray:
    """(G, C) bool: the groups and channels where the candidate (columns ``cols`` at coefficients ``beta``,
    fitted on every train group) ACTS: its contribution there is worth at least one unit of chi-square,
    beta^T G_cell beta / tau >= 1 (noise units, tau the correlation time), i.e. the log's own noise could
    tell it from nothing. A log it does not reach says nothing about it (its gain is noise), and an effect
    with long tails must not be judged on the logs its tails barely touch."""
    n_groups = len(sums.w) // sums.n_channels
    if cols.size == 0:
        return np.zeros((n_groups, sums.n_channels), dtype=bool)
    Gc = sums.G[:, cols][:, :, cols]
    chi2 = np.einsum("i,kij,j->k", beta, Gc, beta) / tau
    return (chi2 >= 1.0).reshape(n_groups, sums.n_channels)


def fitted_exposure(
    sums: GroupSums, idx: np.ndarray, term: np.ndarray, plan: GroupPlan, ridge: Ridge, tau: float
) -> np.ndarray:
    """(G, C) bool: :func:`exposure` of the columns ``term`` (indices into ``sums``' columns, each among ``idx``) at
    their coefficients in the fit of the columns ``idx`` on every train group: where a candidate acts, as the
    held-out passes and the refinement of its scales (:mod:`proxplan.identify.refine`) judge it."""
    beta = solve(sums, idx, trainable_groups(sums, plan), ridge, tau)
    where = {int(j): k for k, j in enumerate(idx)}
    return exposure(sums, term, beta[[where[int(j)] for j in term]], tau)


def gain_test(
    sums: GroupSums,
    without: HeldOutFit,
    with_: HeldOutFit,
    m: int,
    acts: np.ndarray | None = None,
    cluster: np.ndarray | None = None,
    *,
    at_most_one: bool = False,
) -> GainTest:
    """The gain test of :mod:`proxplan.identify.crossval`'s docstring: replacing the held-out fit ``without``
    by ``with_`` (both :class:`~proxplan.identify.crossval.HeldOutFit` over ``sums``), judged on the groups
    and channels where the candidate acts (``acts`` (G, C) bool; default all: a log or a channel the
    candidate cannot touch says nothing about it). Per held-out unit (a flight: the groups of one
    ``cluster`` value, (G,) int; without, each group) the squared error removed, gain = SSE without - SSE
    with, and the energy of the change, |X (beta_with - beta_without)|^2 (:func:`change_energy`), summed
    over its acting cells; then :func:`ratio_test` (``at_most_one`` as there)."""
    w = sums.w.reshape(without.mse.shape)
    gain = (without.mse - with_.mse) * w
    energy = change_energy(sums, without, with_)
    sse = without.mse * w
    ok = np.isfinite(gain) & np.isfinite(energy) & (energy > 0.0)
    if acts is not None:
        ok &= acts
    units = np.arange(len(gain)) if cluster is None else np.asarray(cluster)
    labels = np.unique(units[ok.any(axis=1)])
    g_u, e_u, s_u = (np.array([np.where(ok, x, 0.0)[units == u].sum() for u in labels]) for x in (gain, energy, sse))
    return ratio_test(g_u, e_u, s_u, m, clustered=cluster is not None, at_most_one=at_most_one)


def ratio_test(
    gain: np.ndarray, energy: np.ndarray, sse: np.ndarray, m: int, *, clustered: bool = True, at_most_one: bool = False
) -> GainTest:
    """The one-sided test, Bonferroni over ``m``, that a candidate's held-out predictions remove error: per
    held-out unit (n,) the ``gain`` (squared error removed), the ``energy`` of the change (> 0) and the
    ``sse`` without it (noise units squared). The pooled ratio R = sum gain / sum energy is the weighted
    least-squares slope of gain on energy through the origin with weights 1 / energy (the variance of a
    unit's gain grows with its energy: module docstring of :mod:`proxplan.identify.crossval`); its standard
    error s / sqrt(sum energy), s^2 = sum (gain - R energy)^2 / energy / (n - 1), is estimated from unit to
    unit, so the multiple is Student's t with n - 1 degrees of freedom (``clustered``; else the normal
    quantile).

    ``at_most_one``: the candidate's coefficients were fitted on channels beside the judged ones (a delayed
    effect: fitted on all four, judged on F_z and yaw). If the judged channels hold c times the change its fit
    on every channel makes there, E[R] = 2c - 1 (:mod:`proxplan.identify.crossval`: gain = 2<d, r> - |d|^2 with
    r = c d + noise); an exact shape has c = 1 on every channel, an approximate one some c near it. R above
    :data:`MOST_ELSEWHERE_R` (c = 2) by more than z se says that more than half of what the judged channels
    hold of that shape is something else: not that effect, and it does not pass."""
    n = int(gain.size)
    z = critical_z(m, (n - 1) if clustered else None)
    ratios = gain / np.where(energy > 0, energy, np.nan) if n else np.zeros(0)
    total_e, total_s = float(energy.sum()), float(sse.sum())
    share = float(gain.sum()) / total_s if total_s > 0 else 0.0
    n_eff = effective_units(energy)
    if n < 2 or total_e <= 0.0:
        return GainTest(ratios, float(gain.sum() / total_e) if total_e > 0 else 0.0, float("inf"), z, False, n, share,
                        -np.inf, n_eff)  # fmt: skip
    r = float(gain.sum()) / total_e
    s2 = float(np.sum((gain - r * energy) ** 2 / energy)) / (n - 1)
    se = float(np.sqrt(s2 / total_e))
    too_large = at_most_one and r - MOST_ELSEWHERE_R > z * se
    passed = r > 0.0 and r > z * se and not too_large
    lower = (r - z * se) * total_e / total_s if total_s > 0 else -np.inf
    return GainTest(ratios, r, se, z, bool(passed), n, share, float(lower), n_eff, bool(too_large))


# ------------------------------------------------------------------------------ held-out passes


@dataclass
class Candidate:
    """A named group of columns entering together (a library effect with several linear parameters, or
    one discovered feature on one channel). ``judged_channels``: the wrench channels (of F_z, torque x, y, z)
    its held-out gain is judged on (None: every channel it acts on); it is FITTED on all of them either way
    (a delayed effect: :data:`proxplan.identify.delay_profile.DELAY_CHANNELS`)."""

    name: str
    columns: tuple[str, ...]
    judged_channels: tuple[int, ...] | None = None


@dataclass
class ForwardResult:
    """What the held-out forward selection chose, every test it ran (round, candidate -> GainTest), and
    what the backward pass dropped."""

    chosen: list[str] = field(default_factory=list)
    tests: list[dict[str, GainTest]] = field(default_factory=list)
    dropped: dict[str, GainTest] = field(default_factory=dict)
    final_tests: dict[str, GainTest] = field(default_factory=dict)  # each kept one given all the others
    # kept -> {rival: the kept one's head-to-head gain over the rival}: rivals that also passed in its round
    # and that the flights do not show worse (the data cannot tell the two apart)
    rivals: dict[str, dict[str, GainTest]] = field(default_factory=dict)


def heldout_forward(
    sums: GroupSums,
    always: Sequence[str],
    candidates: Sequence[Candidate],
    plan: GroupPlan,
    ridge: Ridge,
    tau: float,
    *,
    max_terms: int,
    eligible: set[str] | None = None,
    hypothesis: dict[str, str] | None = None,
    fold_eligible: Mapping[str, np.ndarray] | None = None,
    alternatives: Mapping[str, str] | None = None,
) -> ForwardResult:
    """Greedy forward selection by the held-out :func:`gain_test` (Bonferroni over the round's hypotheses
    that could be kept: ``eligible`` candidates, one per ``hypothesis`` label; each round adds the passing
    candidate with the largest lower bound mean - z SE of its gain), then backward: a kept candidate that no longer passes given the others (Bonferroni over
    the kept ones) is dropped, the weakest first. ``eligible`` restricts who may be kept (e.g. the stable
    ones); every candidate is still tested and reported. ``fold_eligible`` (name -> (G,) bool,
    :func:`proxplan.identify.stability.fold_eligibility`) zeroes a candidate's gain on the groups whose flight
    chose it: there the selection run without that flight would not have tested it. ``alternatives`` (name ->
    label): candidates of one label are forms of ONE term (a term with one coefficient and with one per target
    type, :mod:`proxplan.identify.type_split`); once one is kept the others leave the search."""
    cols_of = {c.name: sums.index(c.columns) for c in candidates}
    judged = {c.name: c.judged_channels for c in candidates}
    order = {c.name: i for i, c in enumerate(candidates)}
    base = sums.index(always) if always else np.zeros(0, dtype=int)
    out = ForwardResult()

    def cols(names: Sequence[str]) -> np.ndarray:
        return np.concatenate([base] + [cols_of[n] for n in names]) if names else base

    current = heldout_fit(sums, cols([]), plan, ridge, tau)
    remaining = [c.name for c in candidates]
    label = (lambda n: hypothesis.get(n, n)) if hypothesis else (lambda n: n)
    while remaining and len(out.chosen) < max_terms:
        trials = {}
        for name in remaining:
            trial = _in_fold(
                heldout_fit(sums, cols(out.chosen + [name]), plan, ridge, tau), current, name, fold_eligible
            )
            trials[name] = (trial, _acts(sums, cols, out.chosen, name, cols_of, plan, ridge, tau, judged[name]))
        # Bonferroni over the hypotheses that could be kept: near-duplicate candidates (``hypothesis``: one
        # feature group, its members) test one hypothesis, not several; one that acts on fewer than two
        # flights has no test and cannot be rejected, so it does not count (:func:`can_be_tested`)
        open_ = [
            n for n in remaining if (eligible is None or n in eligible) and can_be_tested(trials[n][1], plan.cluster)
        ]
        m = max(1, len({label(n) for n in open_}))
        tests = {name: gain_test(sums, current, trial, m, acts, plan.cluster, at_most_one=judged[name] is not None)
                 for name, (trial, acts) in trials.items()}  # fmt: skip
        out.tests.append(tests)
        ok = [n for n, t in tests.items() if t.passed and (eligible is None or n in eligible)]
        ok = [n for n in ok if not _needless(n, ok, trials, cols_of, alternatives, sums, plan, order)]
        if not ok:
            break
        # the one most surely better: the largest lower confidence bound of the error it removes (the share at
        # R - z SE), so a candidate whose gain is as large but less consistent over the flights does not
        # pre-empt it
        best = max(ok, key=lambda n: tests[n].share_lower)
        for name, t in tests.items():  # rivals the flights cannot tell from it (a head-to-head one-sided test)
            if name == best or not t.passed or label(name) == label(best):
                continue
            head = gain_test(sums, trials[name][0], trials[best][0], 1, trials[name][1] | trials[best][1], plan.cluster)
            if not head.passed:
                out.rivals.setdefault(best, {})[name] = head
        out.chosen.append(best)
        remaining.remove(best)
        if alternatives is not None and best in alternatives:
            remaining = [n for n in remaining if alternatives.get(n) != alternatives[best]]
        current = heldout_fit(sums, cols(out.chosen), plan, ridge, tau)
    _backward(out, cols, cols_of, sums, plan, ridge, tau, fold_eligible, judged)
    return out


def _needless(name: str, passed: Sequence[str], trials, cols_of, alternatives: Mapping[str, str] | None,
              sums: GroupSums, plan: GroupPlan, order: Mapping[str, int]) -> bool:  # fmt: skip
    """Whether candidate ``name`` is a larger form of a term one of whose smaller forms (fewer columns; of as many
    columns, one offered earlier in ``order``) also ``passed``, and the flights do not show ``name`` better than it
    (the head-to-head gain test, one hypothesis, as a rival's): of two forms of one term the larger (one coefficient
    per target type) or the later (a lever form, :mod:`proxplan.identify.lever_form`) competes only where the data
    ask for it, so where they do not, the round is the round without it."""
    if alternatives is None or name not in alternatives:
        return False
    rank = (len(cols_of[name]), order[name])
    simpler = [n for n in passed if n != name and alternatives.get(n) == alternatives[name]
               and (len(cols_of[n]), order[n]) < rank]  # fmt: skip
    return any(not gain_test(sums, trials[n][0], trials[name][0], 1, trials[n][1] | trials[name][1],
                             plan.cluster).passed for n in simpler)  # fmt: skip


def _in_fold(
    trial: HeldOutFit, without: HeldOutFit, name: str, fold_eligible: Mapping[str, np.ndarray] | None
) -> HeldOutFit:
    """The held-out fit with candidate ``name``, set to the fit ``without`` it on the groups where the
    selection run without their flight would not have tested it (``fold_eligible``; no gain and no change
    there)."""
    if fold_eligible is None or name not in fold_eligible:
        return trial
    return trial.where(np.asarray(fold_eligible[name], dtype=bool), without)


def _acts(
    sums: GroupSums,
    cols,
    others,
    name,
    cols_of,
    plan: GroupPlan,
    ridge: Ridge,
    tau: float,
    channels: tuple[int, ...] | None = None,
) -> np.ndarray:
    """:func:`exposure` of candidate ``name`` fitted on every train group beside ``others``, on its judged
    ``channels`` only (None: all; :attr:`Candidate.judged_channels`)."""
    acts = fitted_exposure(sums, cols(list(others) + [name]), cols_of[name], plan, ridge, tau)
    if channels is not None:
        keep = np.zeros(acts.shape[1], dtype=bool)
        keep[list(channels)] = True
        acts &= keep[None, :]
    return acts


def _backward(
    out: ForwardResult,
    cols,
    cols_of,
    sums: GroupSums,
    plan: GroupPlan,
    ridge: Ridge,
    tau: float,
    fold_eligible: Mapping[str, np.ndarray] | None,
    judged: Mapping[str, tuple[int, ...] | None],
) -> None:
    """Drop from ``out.chosen`` every candidate that no longer passes the gain test given all the others
    (Bonferroni over the kept ones), the weakest first; record each survivor's final test (``judged``: name
    -> its :attr:`Candidate.judged_channels`)."""
    while out.chosen:
        full = heldout_fit(sums, cols(out.chosen), plan, ridge, tau)
        trials = {}
        for name in out.chosen:
            others = [n for n in out.chosen if n != name]
            without = heldout_fit(sums, cols(others), plan, ridge, tau)
            acts = _acts(sums, cols, others, name, cols_of, plan, ridge, tau, judged[name])
            trials[name] = (without, _in_fold(full, without, name, fold_eligible), acts)
        m = max(1, sum(can_be_tested(acts, plan.cluster) for _, _, acts in trials.values()))
        finals = {name: gain_test(sums, w, v, m, acts, plan.cluster, at_most_one=judged[name] is not None)
                  for name, (w, v, acts) in trials.items()}  # fmt: skip
        failing = [n for n, t in finals.items() if not t.passed]
        if not failing:
            out.final_tests = finals
            return
        weakest = min(failing, key=lambda n: finals[n].mean)
        out.dropped[weakest] = finals[weakest]
        out.chosen.remove(weakest)


def heldout_backward(
    sums: GroupSums,
    always: Sequence[str],
    kept: Sequence[Candidate],
    plan: GroupPlan,
    ridge: Ridge,
    tau: float,
    fold_eligible: Mapping[str, np.ndarray] | None = None,
) -> ForwardResult:
    """The backward pass of :func:`heldout_forward` alone, over candidates kept by different stages (the
    library effects and the discovered terms): each must still pass given all the others (``fold_eligible``
    as in :func:`heldout_forward`)."""
    cols_of = {c.name: sums.index(c.columns) for c in kept}
    base = sums.index(always) if always else np.zeros(0, dtype=int)

    def cols(names: Sequence[str]) -> np.ndarray:
        return np.concatenate([base] + [cols_of[n] for n in names]) if names else base

    out = ForwardResult(chosen=[c.name for c in kept])
    _backward(out, cols, cols_of, sums, plan, ridge, tau, fold_eligible, {c.name: c.judged_channels for c in kept})
    return out
