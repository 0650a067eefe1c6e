"""Selection by flights held out: grouped cross-validation and stability selection (issue 35).

Every candidate (a library effect, a discovered term) enters a LINEAR model of the residual of a
reference model, beside the parameters that are always fitted (the calibrated vehicle parameters'
tangent columns, with their priors as a ridge): y ~ X_A beta_A + X_k beta_k. Rows are samples of the
scored vehicles, every wrench channel stacked, in units of each channel's noise (so F_z and the
torques count alike), weighted by the stratified sample's weights; the data term is divided by the
residual's integrated autocorrelation time tau (:func:`proxplan.identify.calibrate.integrated_autocorrelation_time`):
N correlated samples count as N / tau independent ones, which is what sets the priors' weight.

Since the model is linear in the coefficients, everything runs on per-GROUP sums (Gram matrices
X_g^T W X_g, X_g^T W y_g, y_g^T W y_g): leaving a flight out is a subtraction, a resample of the
flights a weighted sum. A group is a flight (the unit that is held out: samples of one flight are not
independent); flights declared ``split: validation`` are only ever held out (never fitted).

**Gain test** (:func:`gain_test`). Each held-out group g gets, per wrench channel c, the log-ratio of its
mean squared error without and with the candidate, bounded by tanh, and its gain is their sum over the
channels the candidate acts on, gain_g = sum_c tanh(ln(MSE_gc(without k) / MSE_gc(with k)) / 2) = sum_c (MSE_without -
MSE_with) / (MSE_without + MSE_with), both from fits that did not see g's flight (leave one train flight
out; validation flights from the fit on every train flight). It is scale-free (flights that hold more
disturbance do not dominate; a term on one channel is not diluted by the others' noise) and bounded by 1
per channel either way, so the spread between logs that hold much or little of an effect, or a channel
whose error is near zero, cannot swamp the mean.
A candidate is judged on the held-out logs and channels where it acts (its contribution, fitted on every
train flight, is worth at least one unit of chi-square there: :func:`exposure`; a jet's effect says nothing
on a vehicle with no source above, a term on F_z nothing on the torques, an effect's far tail nothing
where the noise hides it), and kept only when the mean gain exceeds ``z`` standard errors FROM FLIGHT TO
FLIGHT: the gains of one flight's logs are averaged first (they are predicted by the same fit, the one that
left that flight out, so they are not independent), SE = sd(flight gains) / sqrt(F) over the F flights where
it acts, and z = t_{F-1}^-1(1 - ALPHA / m), Student's t with F - 1 degrees of freedom (the SE itself is
estimated from F values), m the number of candidates tested together: a one-sided test at family-wise level
:data:`ALPHA` (Bonferroni).

**Stability** (:mod:`proxplan.identify.stability`): a candidate must also be chosen in most
half-samples of the flights.

**Both.** Only a stable candidate can be kept, so the Bonferroni count m of the gain test is the number of
stable HYPOTHESES tested together: a candidate no half chose cannot be a false selection, and near-duplicate
candidates (the members of one feature group: a kernel at two widths, a kernel and its lagged copy) stand
for one hypothesis.

**Held-out units** (:func:`plan_groups`): a fit leaves a whole flight out (its CLUSTER), and each
vehicle's log of that flight is one held-out GROUP the channels' acting is decided on; the gain is then
averaged per flight. **Too few flights**:
with one train flight (nothing to hold out) or fewer than :data:`MIN_GROUPS` flights, each train flight
is cut into :data:`FALLBACK_BLOCKS` contiguous blocks in time, and the blocks are the clusters; the note
says so (stderr, JSON, report).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from scipy.stats import norm
from scipy.stats import t as student_t

ALPHA = 0.05
"""Family-wise level of the gain test: on data without any of the m candidates of a round, the
chance that one of them passes, -."""
MIN_GROUPS = 3
"""Fewest held-out clusters (flights) a standard error is taken over (2 degrees of freedom); with fewer,
or a single train flight, the selection falls back to blocks in time."""
FALLBACK_BLOCKS = 5
"""Blocks per train flight when there are too few flights to hold one out."""
RIDGE_EPS = 1e-9
"""Ridge on unpenalised coefficients, relative to their Gram diagonal (numerical safety only), -."""


@dataclass(frozen=True)
class GroupPlan:
    """How the selection's samples are grouped. A GROUP is one vehicle's log of one flight (the unit a held-out
    gain is measured on); a CLUSTER is what a fit leaves out together: the flight (or, in the fallback, a
    block of it in time), so a held-out vehicle is always predicted by a fit that saw none of its flight.
    ``held_out_only`` marks the groups of validation flights (never fitted); ``note`` says what the
    clusters are (a fallback included)."""

    names: tuple[str, ...]
    cluster: np.ndarray  # (G,) int
    held_out_only: np.ndarray  # (G,) bool
    note: str
    fallback: bool = False

    @property
    def n_groups(self) -> int:
        return len(self.names)

    @property
    def n_clusters(self) -> int:
        return int(self.cluster.max()) + 1 if len(self.cluster) else 0


def plan_groups(
    fit: Sequence[tuple[str, str]], valid: Sequence[tuple[str, str]], *, what: str = "selection"
) -> GroupPlan:
    """Groups of the (flight, vehicle) pairs of the train (``fit``) and validation (``valid``) logs: one group
    per pair, clustered by flight, when a fit can leave a flight out (two train flights, or a validation
    flight) and there are at least :data:`MIN_GROUPS` flights to take a standard error over; else the fallback:
    each train flight cut into :data:`FALLBACK_BLOCKS` blocks in time (clusters), a group per block and
    vehicle (:func:`block_ids`)."""
    fit, valid = sorted(set(fit)), sorted(set(valid))
    fit_flights = sorted({f for f, _ in fit})
    valid_flights = sorted({f for f, _ in valid})
    holdable = len(valid_flights) + (len(fit_flights) if len(fit_flights) >= 2 else 0)
    if holdable >= 1 and len(fit_flights) + len(valid_flights) >= MIN_GROUPS:
        flights = fit_flights + valid_flights
        pairs = fit + valid
        names = tuple(f"{f}/{v}" for f, v in pairs)
        cluster = np.array([flights.index(f) for f, _ in pairs])
        held = np.array([False] * len(fit) + [True] * len(valid))
        kinds = f"{len(fit_flights)} train" + (f" + {len(valid_flights)} validation" if valid_flights else "")
        note = (f"{what}: each of {kinds} flights held out in turn (grouped cross-validation by flight); the "
                f"standard error from flight to flight ({len(pairs)} vehicle logs)")  # fmt: skip
        return GroupPlan(names, cluster, held, note)
    blocks = [(f, b) for f in fit_flights for b in range(FALLBACK_BLOCKS)]
    pairs_fb = [(f"{f}#{b}", v) for f, b in blocks for ff, v in fit if ff == f]
    names = tuple(f"{f}/{v}" for f, v in pairs_fb) + tuple(f"{f}/{v}" for f, v in valid)
    cluster = np.array([blocks.index((f.rsplit("#", 1)[0], int(f.rsplit("#", 1)[1]))) for f, _ in pairs_fb]
                       + [len(blocks) + valid_flights.index(f) for f, _ in valid], dtype=int)  # fmt: skip
    held = np.array([False] * len(pairs_fb) + [True] * len(valid))
    note = (
        f"{what}: too few flights to hold one out ({len(fit_flights)} train, {len(valid_flights)} validation; a fit "
        f"must leave a flight out and the gains need {MIN_GROUPS} flights): fell back to {FALLBACK_BLOCKS} "
        "contiguous blocks in time per train flight as what is held out (blocks of one flight share its "
        "conditions: the gains are less certain than a flight's)"
    )
    return GroupPlan(names, cluster, held, note, fallback=True)


def block_ids(t_s: np.ndarray, t_min_s: float, t_max_s: float) -> np.ndarray:
    """Block of :data:`FALLBACK_BLOCKS` (0..) of each sample of clock ``t_s`` (N,) when a flight spanning
    ``t_min_s``..``t_max_s`` (s) is cut into equal blocks."""
    span = max(t_max_s - t_min_s, 1e-9)
    k = np.floor((np.asarray(t_s) - t_min_s) / span * FALLBACK_BLOCKS).astype(int)
    return np.clip(k, 0, FALLBACK_BLOCKS - 1)


# ------------------------------------------------------------------------------ per-group sums


@dataclass(frozen=True)
class GroupSums:
    """Per-cell sums of a linear design: G (K, p, p) = X^T W X, b (K, p) = X^T W y, c (K,) = y^T W y,
    w (K,) = sum of weights of each cell; ``columns`` names the p columns. A cell is a group (flight) and
    a channel: cell k = group * n_channels + channel, so a held-out flight's error is known per channel."""

    columns: tuple[str, ...]
    G: np.ndarray
    b: np.ndarray
    c: np.ndarray
    w: np.ndarray
    n_channels: int = 1

    @staticmethod
    def build(
        x: np.ndarray,
        y: np.ndarray,
        weight: np.ndarray,
        group: np.ndarray,
        n_groups: int,
        columns: Sequence[str],
        *,
        n_channels: int = 1,
    ) -> GroupSums:
        """From rows: ``x`` (M, p), ``y`` (M,), ``weight`` (M,), ``group`` (M,) int cell index in
        0..n_groups * n_channels - 1 (``n_groups`` counts the groups, each split into ``n_channels``)."""
        n_groups = n_groups * n_channels
        p = x.shape[1]
        G = np.zeros((n_groups, p, p))
        b = np.zeros((n_groups, p))
        c = np.zeros(n_groups)
        w = np.zeros(n_groups)
        order = np.argsort(group, kind="stable")
        bounds = np.searchsorted(group[order], np.arange(n_groups + 1))
        for g in range(n_groups):
            idx = order[bounds[g] : bounds[g + 1]]
            if idx.size == 0:
                continue
            sw = np.sqrt(weight[idx])
            xs, ys = x[idx] * sw[:, None], y[idx] * sw
            G[g] = xs.T @ xs
            b[g] = xs.T @ ys
            c[g] = float(ys @ ys)
            w[g] = float(weight[idx].sum())
        return GroupSums(tuple(columns), G, b, c, w, n_channels)

    def cells(self, per_group: np.ndarray) -> np.ndarray:
        """A per-group weight (G,) repeated over each group's channel cells (G * C,)."""
        return np.repeat(np.asarray(per_group, dtype=float), self.n_channels)

    def index(self, names: Sequence[str]) -> np.ndarray:
        pos = {n: k for k, n in enumerate(self.columns)}
        return np.array([pos[n] for n in names], dtype=int)


@dataclass(frozen=True)
class Ridge:
    """Gaussian prior of some coefficients, in data units: ``precision`` (p,) and ``center`` (p,) over
    :attr:`GroupSums.columns` (precision 0: no prior)."""

    precision: np.ndarray
    center: np.ndarray


def solve(sums: GroupSums, cols: np.ndarray, train: np.ndarray, ridge: Ridge, tau: float) -> np.ndarray:
    """Coefficients (len(cols),) of the columns ``cols`` fitted on the groups where ``train`` (groups,) is
    True (weights, or 0/1): argmin sum_g train_g (SSE_g / tau) + ridge terms."""
    train = sums.cells(train)
    G = np.tensordot(train, sums.G[:, cols][:, :, cols], axes=1) / tau
    b = np.tensordot(train, sums.b[:, cols], axes=1) / tau
    prec = ridge.precision[cols]
    A = G + np.diag(prec + RIDGE_EPS * np.maximum(np.diag(G), 1e-300))
    rhs = b + prec * ridge.center[cols]
    try:
        return np.linalg.solve(A, rhs)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(A, rhs, rcond=None)[0]


def group_sse(sums: GroupSums, cols: np.ndarray, beta: np.ndarray, g: int) -> float:
    """Weighted SSE of group ``g`` with coefficients ``beta`` on ``cols``, noise units."""
    Gg = sums.G[g][np.ix_(cols, cols)]
    return float(sums.c[g] - 2.0 * beta @ sums.b[g, cols] + beta @ Gg @ beta)


def group_weights(sums: GroupSums) -> np.ndarray:
    """(G,) total weight of each group over its channels."""
    return sums.w.reshape(-1, sums.n_channels).sum(axis=1)


def trainable_groups(sums: GroupSums, plan: GroupPlan) -> np.ndarray:
    """(G,) 0/1: the groups a fit may use (train groups with samples)."""
    return ((~plan.held_out_only) & (group_weights(sums) > 0)).astype(float)


def heldout_mse(sums: GroupSums, cols: np.ndarray, plan: GroupPlan, ridge: Ridge, tau: float) -> np.ndarray:
    """(G, C): per group and channel, the mean squared error (noise units) predicted by a fit that did not
    see the group's cluster (its flight): each train cluster left out in turn; validation groups from the fit
    on every train group. NaN where a group has no samples."""
    nc = sums.n_channels
    trainable = trainable_groups(sums, plan)
    weights = group_weights(sums)
    out = np.full((plan.n_groups, nc), np.nan)
    beta_all = solve(sums, cols, trainable, ridge, tau)
    for c in range(plan.n_clusters):
        members = np.flatnonzero((plan.cluster == c) & (weights > 0))
        if members.size == 0:
            continue
        if plan.held_out_only[members].all():
            beta = beta_all
        else:
            mask = trainable * (plan.cluster != c)
            if not mask.any():
                continue
            beta = solve(sums, cols, mask, ridge, tau)
        for g in members:
            for ch in range(nc):
                cell = g * nc + ch
                if sums.w[cell] > 0:
                    out[g, ch] = group_sse(sums, cols, beta, int(cell)) / sums.w[cell]
    return out


def heldout_predictions(
    sums: GroupSums, x: np.ndarray, group: np.ndarray, cols: np.ndarray, plan: GroupPlan, ridge: Ridge, tau: float
) -> np.ndarray:
    """(N, C) each row's prediction by the fit that did not see its cluster (its flight; a validation row: the
    fit on every train group), from the rows' design ``x`` (N, C, p) over :attr:`GroupSums.columns` and their
    ``group`` (N,)."""
    out = np.zeros(x.shape[:2])
    trainable = trainable_groups(sums, plan)
    beta_all = solve(sums, cols, trainable, ridge, tau)
    row_cluster = plan.cluster[group]
    for c in range(plan.n_clusters):
        rows = np.flatnonzero(row_cluster == c)
        if rows.size == 0:
            continue
        members = plan.cluster == c
        mask = trainable * ~members
        beta = beta_all if plan.held_out_only[members].all() or not mask.any() else solve(sums, cols, mask, ridge, tau)
        out[rows] = x[rows][:, :, cols] @ beta
    return out


@dataclass(frozen=True)
class GainTest:
    """The held-out gain of one candidate: per-group gains (bounded log-ratio of held-out MSEs, summed over
    the channels, -), their mean and standard error over the groups, the critical multiple z and whether it
    passed."""

    gains: np.ndarray
    mean: float
    se: float
    z: float
    passed: bool
    n_groups: int

    @property
    def t(self) -> float:
        return self.mean / self.se if self.se > 0 else (np.inf if self.mean > 0 else 0.0)

    def to_json(self) -> dict[str, float | int | bool | None]:
        return {"mean_gain": self.mean, "se": self.se, "t": float(self.t) if np.isfinite(self.t) else None,
                "z_required": self.z, "passed": self.passed, "n_groups": self.n_groups}  # fmt: skip


def critical_z(m: int, dof: int | None = None) -> float:
    """The one-sided Bonferroni multiple for m candidates tested together, -: Student's t_dof^-1(1 - ALPHA / m)
    for a standard error estimated from dof + 1 values, Phi^-1(1 - ALPHA / m) when ``dof`` is None."""
    q = 1.0 - ALPHA / max(int(m), 1)
    return float(norm.ppf(q) if dof is None else student_t.ppf(q, max(int(dof), 1)))


def relative_gains(mse_without: np.ndarray, mse_with: np.ndarray, acts: np.ndarray | None = None) -> np.ndarray:
    """(G,) per group, the sum over its channels of (MSE without - MSE with) / (MSE without + MSE with) of
    (G, C) held-out MSEs, i.e. tanh(ln(MSE without / MSE with) / 2): the log-ratio of the errors, bounded to
    +-1 per channel, over the channels where the candidate acts (``acts`` (G, C) bool; default all; a
    channel without error on both sides adds nothing); NaN for a group with no such channel."""
    a, b = np.atleast_2d(mse_without), np.atleast_2d(mse_with)
    ok = np.isfinite(a) & np.isfinite(b) & (a + b > 0)
    if acts is not None:
        ok &= acts
    share = np.where(ok, (np.where(ok, a, 0.0) - np.where(ok, b, 0.0)) / np.where(ok, a + b, 1.0), 0.0)
    return np.where(ok.any(axis=1), share.sum(axis=1), np.nan)


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


def gain_test(
    mse_without: np.ndarray,
    mse_with: np.ndarray,
    m: int,
    acts: np.ndarray | None = None,
    cluster: np.ndarray | None = None,
) -> GainTest:
    """The gain test of the module docstring on (G, C) held-out MSEs (:func:`relative_gains`), over the
    groups and channels where the candidate acts (``acts``, (G, C) bool; default all): a log or a channel
    the candidate cannot touch (a vehicle with no source above for a jet's effect, the torques for a term
    on F_z) says nothing about it. With ``cluster`` ((G,) int, each group's flight) the groups' gains are
    averaged per cluster and the test is over clusters (Student's t); without, over groups (normal)."""
    return flight_test(relative_gains(mse_without, mse_with, acts), m, cluster)


def flight_test(d: np.ndarray, m: int, cluster: np.ndarray | None = None) -> GainTest:
    """The one-sided test that the mean of per-group values ``d`` ((G,), NaN: the group says nothing) is
    positive beyond chance, Bonferroni over ``m``: with ``cluster`` ((G,) int, each group's flight) the values
    are averaged per cluster first and the critical multiple is Student's t over the clusters; without, the
    normal quantile over the groups."""
    if cluster is not None:
        ok = np.isfinite(d)
        d = np.array([d[ok & (cluster == c)].mean() for c in np.unique(cluster[ok])])
    d = d[np.isfinite(d)]
    n = int(d.size)
    z = critical_z(m, None if cluster is None else n - 1)
    if n < 2:
        return GainTest(d, float(d.mean()) if n else 0.0, float("inf"), z, False, n)
    mean = float(d.mean())
    se = float(d.std(ddof=1) / np.sqrt(n))
    passed = mean > 0.0 and (mean > z * se)
    return GainTest(d, mean, se, z, bool(passed), n)


# ------------------------------------------------------------------------------ held-out passes


@dataclass
class Candidate:
    """A named group of columns entering together (a library effect with several linear parameters, or
    one discovered feature on one channel)."""

    name: str
    columns: tuple[str, ...]


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
) -> ForwardResult:
    """Greedy forward selection by the held-out :func:`gain_test` (Bonferroni over the round's hypotheses
    that could be kept: ``eligible`` candidates, one per ``hypothesis`` label; each round adds the passing
    candidate with the largest lower bound mean - z SE of its gain), then backward: a kept candidate that no longer passes given the others (Bonferroni over
    the kept ones) is dropped, the weakest first. ``eligible`` restricts who may be kept (e.g. the stable
    ones); every candidate is still tested and reported."""
    cols_of = {c.name: sums.index(c.columns) for c in candidates}
    base = sums.index(always) if always else np.zeros(0, dtype=int)
    out = ForwardResult()

    def cols(names: Sequence[str]) -> np.ndarray:
        return np.concatenate([base] + [cols_of[n] for n in names]) if names else base

    current = heldout_mse(sums, cols([]), plan, ridge, tau)
    remaining = [c.name for c in candidates]
    while remaining and len(out.chosen) < max_terms:
        tests = {}
        # Bonferroni over the hypotheses that could be kept: near-duplicate candidates (``hypothesis``: one
        # feature group, its members) test one hypothesis, not several
        open_ = [n for n in remaining if eligible is None or n in eligible]
        m = max(1, len({hypothesis.get(n, n) if hypothesis else n for n in open_}))
        trials = {}
        for name in remaining:
            trial = heldout_mse(sums, cols(out.chosen + [name]), plan, ridge, tau)
            acts = _acts(sums, cols, out.chosen, name, cols_of, plan, ridge, tau)
            tests[name] = gain_test(current, trial, m, acts, plan.cluster)
            trials[name] = (trial, acts)
        out.tests.append(tests)
        ok = [n for n, t in tests.items() if t.passed and (eligible is None or n in eligible)]
        if not ok:
            break
        # the one most surely better: the largest lower confidence bound of the gain (mean - z SE), so a
        # candidate whose gain is as large but less consistent over the flights does not pre-empt it
        best = max(ok, key=lambda n: tests[n].mean - tests[n].z * tests[n].se)
        label = (lambda n: hypothesis.get(n, n)) if hypothesis else (lambda n: n)
        for name, t in tests.items():  # rivals the flights cannot tell from it (a head-to-head one-sided test)
            if name == best or not t.passed or label(name) == label(best):
                continue
            head = gain_test(trials[name][0], trials[best][0], 1, trials[name][1] | trials[best][1], plan.cluster)
            if not head.passed:
                out.rivals.setdefault(best, {})[name] = head
        out.chosen.append(best)
        remaining.remove(best)
        current = heldout_mse(sums, cols(out.chosen), plan, ridge, tau)
    _backward(out, cols, cols_of, sums, plan, ridge, tau)
    return out


def _acts(sums: GroupSums, cols, others, name, cols_of, plan: GroupPlan, ridge: Ridge, tau: float) -> np.ndarray:
    """:func:`exposure` of candidate ``name`` fitted on every train group beside ``others``."""
    idx = cols(list(others) + [name])
    beta = solve(sums, idx, trainable_groups(sums, plan), ridge, tau)
    return exposure(sums, cols_of[name], beta[-len(cols_of[name]) :], tau)


def _backward(out: ForwardResult, cols, cols_of, sums: GroupSums, plan: GroupPlan, ridge: Ridge, tau: float) -> None:
    """Drop from ``out.chosen`` every candidate that no longer passes the gain test given all the others
    (Bonferroni over the kept ones), the weakest first; record each survivor's final test."""
    while out.chosen:
        full = heldout_mse(sums, cols(out.chosen), plan, ridge, tau)
        finals = {}
        for name in out.chosen:
            others = [n for n in out.chosen if n != name]
            without = heldout_mse(sums, cols(others), plan, ridge, tau)
            acts = _acts(sums, cols, others, name, cols_of, plan, ridge, tau)
            finals[name] = gain_test(without, full, len(out.chosen), acts, plan.cluster)
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
) -> ForwardResult:
    """The backward pass of :func:`heldout_forward` alone, over candidates kept by different stages (the
    library effects and the discovered terms): each must still pass given all the others."""
    cols_of = {c.name: sums.index(c.columns) for c in kept}
    base = sums.index(always) if always else np.zeros(0, dtype=int)

    def cols(names: Sequence[str]) -> np.ndarray:
        return np.concatenate([base] + [cols_of[n] for n in names]) if names else base

    out = ForwardResult(chosen=[c.name for c in kept])
    _backward(out, cols, cols_of, sums, plan, ridge, tau)
    return out
