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

**Gain test** (:func:`proxplan.identify.heldout_select.gain_test`). Adding a candidate k replaces the
held-out fit without it (coefficients beta_0 from a fit that did not see the flight) by the one with it
(beta_1, from the same flights). On a held-out flight, with r = y - X beta_0 its residual without k and
d = X (beta_1 - beta_0) what k's fit changes there, both weighted sums over its samples and the channels
where k acts (noise units):

    gain_f = |r|^2 - |r - d|^2 = 2 <d, r> - |d|^2,    energy_f = |d|^2   (:func:`change_energy`).

If k is no effect of the data, d is fitted to other flights' noise and independent of r on this one:
E[gain_f] = -energy_f (a change that explains nothing costs its own size), and <d, r> has variance
sigma^2 energy_f for noise of variance sigma^2 per unit, so Var(gain_f) grows in proportion to energy_f.
If k is the effect and its fit carries over, r contains d: gain_f = energy_f + 2 <d, noise> (a
least-squares fit removes what it changes), whatever the flight's exposure to it, a flight that holds
much of the effect or little. So the held-out evidence is the ratio of the two: the pooled
R = sum_f gain_f / sum_f energy_f is the weighted least-squares slope of gain on energy through the
origin with weights 1 / energy_f (the variance above), -1 for a term fitted to noise and 1 for an effect
that carries over to flights it was not fitted on; R > 0 means the candidate's predictions remove more
error on new flights than they add. Its standard error is taken FROM FLIGHT TO FLIGHT,
SE = s / sqrt(sum energy), s^2 = sum_f (gain_f - R energy_f)^2 / energy_f / (F - 1), so a flight whose
misfit the candidate happens to follow (the model's flight-to-flight error, larger than the noise) widens
it; the candidate is kept only when R > z SE, z = t_{F-1}^-1(1 - ALPHA / m), Student's t with F - 1 degrees
of freedom (s is estimated from F flights), m the number of candidates tested together: a one-sided test at
family-wise level :data:`proxplan.identify.heldout_select.ALPHA` (Bonferroni). (Why it replaced the plain
mean of a bounded per-flight log-ratio of errors: docs/identify.md, "The gain".)
A flight's logs are summed first (they are predicted by the same fit, the one that left that flight out,
so they are not independent). A candidate is judged on the held-out logs and channels where it acts (its
contribution, fitted on every train flight, is worth at least one unit of chi-square there:
:func:`proxplan.identify.heldout_select.exposure`; a jet's effect says nothing on a vehicle with no source
above, a term on F_z nothing on the torques, an effect's far tail nothing where the noise hides it).

**Stability** (:mod:`proxplan.identify.stability`): a candidate must also be chosen in most
half-samples of the flights.

**Both.** Only a stable candidate can be kept, so the Bonferroni count m of the gain test is the number of
stable HYPOTHESES tested together: a candidate no half chose cannot be a false selection, and near-duplicate
candidates (the members of one feature group: a kernel at two widths, a kernel and its lagged copy) stand
for one hypothesis. Since stability was judged on every flight, the held-out flight included, a
discovered term's gain on a flight counts only where the search run WITHOUT that flight would have tested
it; elsewhere that procedure changes nothing on the flight (gain and energy 0: the flight drops out of the
ratio) (:func:`proxplan.identify.stability.fold_eligibility`: cross-validation of the selection step
itself; for the discovered terms, chosen among some 1500, not the nine named effects).

**Held-out units** (:func:`plan_groups`): a fit leaves a whole flight out (its CLUSTER), and each
vehicle's log of that flight is one held-out GROUP the channels' acting is decided on; the gain is then
averaged per flight. **Too few flights**:
with one train flight (nothing to hold out) or fewer than :data:`MIN_GROUPS` flights, each train flight
is cut into :data:`FALLBACK_BLOCKS` contiguous blocks in time, and the blocks are the clusters; the note
says so (stderr, JSON, report).

The gain test and the forward / backward passes built on these held-out fits are in
:mod:`proxplan.identify.heldout_select`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

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
    return _Restricted.of(sums, cols, ridge).solve(train, tau)


def solve_carried(
    sums: GroupSums,
    cols: np.ndarray,
    carried: np.ndarray,
    train: np.ndarray,
    ridge: Ridge,
    tau: float,
) -> np.ndarray:
    """Coefficients (len(cols),) of the columns ``cols`` where each column ``cols[j]`` with ``carried[j] >= 0``
    also drags the column ``carried[j]`` (an index into :attr:`GroupSums.columns`) along at the SAME
    coefficient, without that column informing it: the prediction is sum_j beta_j (x_cols[j] + x_carried[j]),
    and beta is the fixed point at which :func:`solve` on ``cols`` against the target LESS the carried part
    returns beta again. Normal equations of that fit, G_cc beta = b_c - G_c,carried beta (sums over the train
    groups, ridge as :func:`solve`), solved directly as one (non-symmetric) linear system, so no iteration.

    Used where the vehicle parameters' steps are fitted on F_z alone but act on every channel
    (:func:`proxplan.identify.selection.joint_model`): ``cols`` hold their F_z parts, ``carried`` their torque
    parts, and the terms fitted on the torque channels see the residual the steps leave there."""
    restricted = _Restricted.of(sums, cols, ridge)
    G, b = restricted.sums_of(train)
    cells = sums.cells(train)
    for j in np.flatnonzero(np.asarray(carried) >= 0):
        # the carried column at coefficient beta_j moves to the left side: G[:, j] += X_c^T W x_carried
        G[:, j] = G[:, j] + np.tensordot(cells, sums.G[:, cols, int(carried[j])], axes=1)
    return restricted.solve_sums(G, b, tau)


@dataclass(frozen=True)
class _Restricted:
    """The per-cell sums and the prior restricted to the columns ``cols`` once (a held-out pass fits the
    same columns once per cluster): G (K, q, q), b (K, q), precision and center (q,)."""

    sums: GroupSums
    G: np.ndarray
    b: np.ndarray
    precision: np.ndarray
    center: np.ndarray

    @staticmethod
    def of(sums: GroupSums, cols: np.ndarray, ridge: Ridge) -> _Restricted:
        return _Restricted(
            sums, sums.G[:, cols[:, None], cols[None, :]], sums.b[:, cols], ridge.precision[cols], ridge.center[cols]
        )

    def solve(self, train: np.ndarray, tau: float) -> np.ndarray:
        """:func:`solve` on these columns."""
        cells = self.sums.cells(train)
        return self.solve_sums(np.tensordot(cells, self.G, axes=1), np.tensordot(cells, self.b, axes=1), tau)

    def solve_without(self, total: tuple[np.ndarray, np.ndarray], groups: np.ndarray, tau: float) -> np.ndarray:
        """:func:`solve` on the 0/1 train groups whose sums are ``total`` (:meth:`sums_of`), less the train
        groups ``groups`` (int array): leaving a flight out is a subtraction."""
        cells = (groups[:, None] * self.sums.n_channels + np.arange(self.sums.n_channels)[None, :]).ravel()
        return self.solve_sums(total[0] - self.G[cells].sum(axis=0), total[1] - self.b[cells].sum(axis=0), tau)

    def sums_of(self, train: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(G (q, q), b (q,)) summed over the groups weighted by ``train`` (groups,)."""
        cells = self.sums.cells(train)
        return np.tensordot(cells, self.G, axes=1), np.tensordot(cells, self.b, axes=1)

    def solve_sums(self, G: np.ndarray, b: np.ndarray, tau: float) -> np.ndarray:
        """:func:`solve` from the train groups' summed G (q, q) and b (q,)."""
        G, b = G / tau, b / tau
        A = G + np.diag(self.precision + RIDGE_EPS * np.maximum(np.diag(G), 1e-300))
        rhs = b + self.precision * self.center
        try:
            return np.linalg.solve(A, rhs)
        except np.linalg.LinAlgError:
            return np.linalg.lstsq(A, rhs, rcond=None)[0]

    def mse(self, beta: np.ndarray, cells: np.ndarray) -> np.ndarray:
        """(len(cells),) weighted mean squared error of the cells with coefficients ``beta``, noise units
        (NaN where a cell has no weight)."""
        sse = self.sums.c[cells] - 2.0 * (self.b[cells] @ beta) + np.einsum("kij,i,j->k", self.G[cells], beta, beta)
        w = self.sums.w[cells]
        return np.where(w > 0, sse / np.where(w > 0, w, 1.0), np.nan)


def group_weights(sums: GroupSums) -> np.ndarray:
    """(G,) total weight of each group over its channels."""
    return sums.w.reshape(-1, sums.n_channels).sum(axis=1)


def trainable_groups(sums: GroupSums, plan: GroupPlan) -> np.ndarray:
    """(G,) 0/1: the groups a fit may use (train groups with samples)."""
    return ((~plan.held_out_only) & (group_weights(sums) > 0)).astype(float)


@dataclass(frozen=True)
class HeldOutFit:
    """The held-out predictions of one set of columns: ``mse`` (G, C), per group and channel, the mean squared
    error (noise units) of the fit that did not see the group's cluster (its flight), NaN where a group has no
    samples; ``beta`` (G, p) that fit's coefficients over all :attr:`GroupSums.columns` (0 outside ``cols``,
    NaN rows where there was no fit); ``cols`` the fitted columns (indices into :attr:`GroupSums.columns`)."""

    mse: np.ndarray
    beta: np.ndarray
    cols: np.ndarray

    def where(self, keep: np.ndarray, other: HeldOutFit) -> HeldOutFit:
        """This fit on the groups where ``keep`` (G,) bool, ``other``'s elsewhere."""
        return HeldOutFit(np.where(keep[:, None], self.mse, other.mse), np.where(keep[:, None], self.beta, other.beta),
                          np.union1d(self.cols, other.cols))  # fmt: skip


def heldout_fit(sums: GroupSums, cols: np.ndarray, plan: GroupPlan, ridge: Ridge, tau: float) -> HeldOutFit:
    """The :class:`HeldOutFit` of the columns ``cols``: each train cluster left out in turn; validation groups
    from the fit on every train group."""
    nc = sums.n_channels
    trainable = trainable_groups(sums, plan)
    weights = group_weights(sums)
    out = np.full((plan.n_groups, nc), np.nan)
    betas = np.full((plan.n_groups, len(sums.columns)), np.nan)
    sub = _Restricted.of(sums, cols, ridge)
    total = sub.sums_of(trainable)
    beta_all = sub.solve_sums(*total, tau)
    for c in range(plan.n_clusters):
        members = np.flatnonzero((plan.cluster == c) & (weights > 0))
        if members.size == 0:
            continue
        if plan.held_out_only[members].all():
            beta = beta_all
        else:
            if not (trainable * (plan.cluster != c)).any():
                continue
            beta = sub.solve_without(total, np.flatnonzero((plan.cluster == c) & (trainable > 0)), tau)
        cells = (members[:, None] * nc + np.arange(nc)[None, :]).ravel()
        out[members] = sub.mse(beta, cells).reshape(members.size, nc)
        betas[members] = 0.0
        betas[np.ix_(members, cols)] = beta
    return HeldOutFit(out, betas, np.asarray(cols, dtype=int))


def heldout_mse(sums: GroupSums, cols: np.ndarray, plan: GroupPlan, ridge: Ridge, tau: float) -> np.ndarray:
    """(G, C): the held-out mean squared errors of :func:`heldout_fit` (noise units)."""
    return heldout_fit(sums, cols, plan, ridge, tau).mse


def change_energy(sums: GroupSums, a: HeldOutFit, b: HeldOutFit) -> np.ndarray:
    """(G, C) per group and channel, the weighted sum over its samples of the squared difference between the
    held-out predictions of ``b`` and ``a`` (noise units squared): |X (beta_b - beta_a)|^2, the energy of what
    replacing fit ``a`` by ``b`` changes on data neither saw. NaN where either has no fit."""
    cols = np.union1d(a.cols, b.cols)
    n_groups = a.mse.shape[0]
    delta = b.beta[:, cols] - a.beta[:, cols]  # (G, q)
    Gq = sums.G[:, cols[:, None], cols[None, :]].reshape(n_groups, sums.n_channels, len(cols), len(cols))
    return np.einsum("gi,gcij,gj->gc", delta, Gq, delta)


def heldout_predictions(
    sums: GroupSums, x: np.ndarray, group: np.ndarray, cols: np.ndarray, plan: GroupPlan, ridge: Ridge, tau: float
) -> np.ndarray:
    """(N, C) each row's prediction by the fit that did not see its cluster (its flight; a validation row: the
    fit on every train group), from the rows' design ``x`` (N, C, p) over :attr:`GroupSums.columns` and their
    ``group`` (N,)."""
    out = np.zeros(x.shape[:2])
    trainable = trainable_groups(sums, plan)
    sub = _Restricted.of(sums, cols, ridge)
    beta_all = sub.solve(trainable, tau)
    row_cluster = plan.cluster[group]
    for c in range(plan.n_clusters):
        rows = np.flatnonzero(row_cluster == c)
        if rows.size == 0:
            continue
        members = plan.cluster == c
        mask = trainable * ~members
        beta = beta_all if plan.held_out_only[members].all() or not mask.any() else sub.solve(mask, tau)
        out[rows] = x[rows][:, :, cols] @ beta
    return out
