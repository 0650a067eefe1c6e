"""A kept multi-scale kernel's width and decay length, refined off the declared grid by flights held out (issue 35).

The dictionary holds the kernels of a neighbour above, below or beside on a coarse grid of scales
(:data:`proxplan.physics.basis.BASIS_WIDTHS_L`, ratio 2.5; :data:`~proxplan.physics.basis.BASIS_DECAYS_L`, ratio 4):
a finer grid would multiply a dictionary of ~580 features for every search. But a term fitted at the nearest
grid scale carries the train flights' coefficient to other distances with the wrong shape: the error of an
exponential decay fitted at q times the true length grows as exp(x |1 - 1/q|) with the depth x (in decay
lengths), and with q up to sqrt(4) = 2 a term fitted where two vehicles passed close is half again too strong
or too weak on a flight two decay lengths further apart (the same argument that put the ground proximity on a
fine series, stop 67; :data:`proxplan.physics.features.GROUND_SCALE_STEPS`).

So, once discovery has KEPT a kernel term (its hypothesis tested as before, at its grid scale), its width and
decay length are searched continuously within one grid step of the kept scale on each side (the neighbours'
territory: the grid's own ratios, :data:`WIDTH_RATIO`, :data:`DECAY_RATIO`), each in turn, by the criterion
selection uses to judge it: the error of every train flight predicted by the joint fit that did not see it (the
kept effects, the vehicle parameters' tangents and the other kept terms refitted beside it,
:func:`proxplan.identify.crossval.heldout_fit`).

The best scales found are chosen BY those held-out errors, so their own held-out error is optimistic: searched
over ~40 scales, noise alone finds a "better" one. The refined term therefore replaces the grid term only where
it passes the gain test every term passes (:func:`proxplan.identify.heldout_select.gain_test`, one hypothesis at
the level :data:`proxplan.identify.heldout_select.ALPHA`), with each flight judged at the scales the search would
have chosen without that flight's error (the scales tried that minimise the OTHER train flights' held-out error;
selection inside the fold, so the flight judged played no part in choosing them). No constant is set here: the
level is the term test's, the bracket the grid's. A refined term is named by its scales
(``above_g0p774L_e2p31L_1``) and evaluated by that name (:func:`proxplan.physics.basis.parse_basis_name`).

Search (counts, the same on every machine): per coordinate a log-spaced scan of :data:`SCAN_POINTS` points over
the bracket, then :data:`GOLDEN_STEPS` golden-section steps between the best point's neighbours; width then
decay length, :data:`SWEEPS` times.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace

import numpy as np

from proxplan.identify.crossval import HeldOutFit, Ridge, heldout_fit, trainable_groups
from proxplan.identify.data import unit_inputs
from proxplan.identify.design import CHANNELS, SelectionSet
from proxplan.identify.heldout_select import GainTest, gain_test
from proxplan.physics import (
    BASIS_DECAYS_L,
    BASIS_WIDTHS_L,
    BasisKernel,
    basis_columns,
    neighbour_motion,
    parse_basis_name,
    parse_term_key,
    weight_scaled,
)

__all__ = [
    "DECAY_RATIO",
    "GOLDEN_STEPS",
    "SCAN_POINTS",
    "SWEEPS",
    "WIDTH_RATIO",
    "Refined",
    "refine_kernel_terms",
    "term_column",
]

WIDTH_RATIO = BASIS_WIDTHS_L[1] / BASIS_WIDTHS_L[0]
"""A width is searched within this ratio of the kept grid width on each side (the grid's own step: 2.5), -."""
DECAY_RATIO = BASIS_DECAYS_L[1] / BASIS_DECAYS_L[0]
"""A decay length is searched within this ratio of the kept grid length on each side (the grid's step: 4), -."""
SCAN_POINTS = 9
"""Log-spaced points of the scan over a bracket (the kept scale its middle one): a step of ratio
ratio^(1/4) (1.26 for the width, 1.41 for the decay), the golden steps then resolve within it, -."""
GOLDEN_STEPS = 8
"""Golden-section steps within the best scan point's neighbours: the interval shrinks 0.618^8 = 0.021 times,
to a ratio under 1.01 of the scale, -."""
SWEEPS = 2
"""Passes over (width, decay length): the second re-tunes each at the other's refined value, -."""


@dataclass(frozen=True)
class Refined:
    """One kept kernel term's refinement: ``origin`` the grid term's key, ``key`` the refined term's key (the
    scales searched best), the summed held-out squared error of the train flights (noise units) at the grid scales
    and at the refined ones, ``test`` the gain test of replacing the grid term by the refined one with its scales
    chosen without the flight judged (module docstring), ``accepted`` whether it passed (then ``key`` stands in
    the model), ``evaluations`` the scales evaluated."""

    key: str
    origin: str
    heldout_grid: float
    heldout_refined: float
    test: GainTest
    evaluations: int
    column: np.ndarray = field(repr=False, compare=False)  # (N, 4) the refined term's column, noise units

    @property
    def accepted(self) -> bool:
        return self.test.passed

    def to_json(self) -> dict[str, object]:
        return {"key": self.key, "from": self.origin, "accepted": self.accepted, "heldout_mse_grid": self.heldout_grid,
                "heldout_mse_refined": self.heldout_refined, "test": self.test.to_json(),
                "evaluations": self.evaluations}  # fmt: skip


class _Neighbours:
    """Per selection sample, each neighbour's offset, size and relative velocity (full-resolution units,
    taken at the sampled rows), so a kernel at any scale is one vectorised call."""

    def __init__(self, sel: SelectionSet) -> None:
        order = np.argsort(sel.rows, kind="stable")
        rows_sorted = sel.rows[order]
        self.parts: list[tuple[np.ndarray, list[tuple[np.ndarray, float, np.ndarray]]]] = []
        start = 0
        for u in sel.sources:
            lo, hi = np.searchsorted(rows_sorted, [start, start + len(u)])
            if hi > lo:
                at = rows_sorted[lo:hi] - start
                motion = neighbour_motion(unit_inputs(u, sel.model))
                self.parts.append((order[lo:hi], [(off[at], size, v[at]) for off, size, v in motion]))
            start += len(u)
        self.n = len(sel.rows)

    def feature(self, kernel: BasisKernel, axis: str) -> np.ndarray:
        """(N,) the feature ``kernel.name(axis)`` at every selection sample."""
        out = np.zeros(self.n)
        name = kernel.name(axis)
        for where, motion in self.parts:
            for off, size, v_rel in motion:
                out[where] += basis_columns(kernel, (axis,), off, size, np.hypot(v_rel[:, 0], v_rel[:, 1]))[name]
        return out


def term_column(sel: SelectionSet, key: str, x: np.ndarray) -> np.ndarray:
    """(N, 4) the column of term ``key`` (noise units) from its feature's values ``x`` (N,): on its channel, scaled
    to the target where the term is weight-scaled (:func:`proxplan.physics.feature_terms.term_scale`)."""
    channel, _ = parse_term_key(key)
    c = CHANNELS.index(channel)
    col = np.zeros((len(x), len(CHANNELS)))
    scale = sel.target_scale(channel) if weight_scaled(key) else 1.0
    col[:, c] = x * scale / sel.row_scale[:, c]
    return col


def _golden_min(f: Callable[[float], float], a: float, b: float, steps: int) -> tuple[float, float]:
    """The best (x, f(x)) a golden-section search of ``steps`` steps finds on [a, b]."""
    g = (np.sqrt(5.0) - 1.0) / 2.0
    c, d = b - g * (b - a), a + g * (b - a)
    fc, fd = f(c), f(d)
    for _ in range(steps):
        if fc <= fd:
            b, d, fd = d, c, fc
            c = b - g * (b - a)
            fc = f(c)
        else:
            a, c, fc = c, d, fd
            d = a + g * (b - a)
            fd = f(d)
    return (c, fc) if fc <= fd else (d, fd)


class _ScaleSearch:
    """The held-out error of one kept kernel term at the scales tried: each train flight's summed squared error
    (noise units) predicted by the joint fit of the term at those scales and the ``others`` columns on the other
    train flights, memoised per (width, decay length) as rounded in the name."""

    def __init__(self, sel: SelectionSet, neighbours: _Neighbours, key: str, kernel: BasisKernel, axis: str,
                 others: Mapping[str, np.ndarray], ridge_of: Callable[[tuple[str, ...]], Ridge]) -> None:  # fmt: skip
        self.sel, self.neighbours, self.key, self.kernel, self.axis = sel, neighbours, key, kernel, axis
        self.others, self.ridge_of = dict(others), ridge_of
        self.per_flight: dict[tuple[float, float], np.ndarray] = {}  # scales -> (clusters,) held-out SSE

    @staticmethod
    def rounded(width_L: float, decay_L: float) -> tuple[float, float]:
        """The scales as the feature's name holds them (three significant digits), in L."""
        return float(f"{width_L:.3g}"), float(f"{decay_L:.3g}")

    def scaled(self, at: tuple[float, float]) -> BasisKernel:
        return replace(self.kernel, width_L=at[0], decay_L=at[1])

    def column(self, at: tuple[float, float]) -> np.ndarray:
        """(N, 4) the term's column at the scales ``at``, noise units."""
        return term_column(self.sel, self.key, self.neighbours.feature(self.scaled(at), self.axis))

    def cost(self, width_L: float, decay_L: float) -> float:
        """The summed held-out squared error of the train flights at these scales (noise units)."""
        at = self.rounded(width_L, decay_L)
        if at not in self.per_flight:
            sums = self.sel.sums({**self.others, self.key: self.column(at)})
            fit = heldout_fit(sums, np.arange(len(sums.columns)), self.sel.plan, self.ridge_of(sums.columns),
                              self.sel.tau)  # fmt: skip
            self.per_flight[at] = _per_train_flight(sums, fit, self.sel.plan)
        return float(self.per_flight[at].sum())

    def best_width(self, decay_L: float) -> float:
        """The width (L) within the bracket round the grid width with the lowest :meth:`cost` at ``decay_L``."""
        return _line(lambda w: self.cost(w, decay_L), self.kernel.width_L, WIDTH_RATIO)

    def best_decay(self, width_L: float) -> float:
        """The decay length (L) within the bracket round the grid one with the lowest :meth:`cost` at ``width_L``."""
        return _line(lambda d: self.cost(width_L, d), self.kernel.decay_L, DECAY_RATIO)

    def chosen_without(self, cluster: int) -> tuple[float, float]:
        """The scales tried that predict the train flights other than ``cluster``'s best (the choice a search
        that never saw that flight's error would make)."""
        return min(self.per_flight, key=lambda at: float(self.per_flight[at].sum() - self.per_flight[at][cluster]))

    def test(self, best: tuple[float, float]) -> GainTest:
        """The gain test (:func:`proxplan.identify.heldout_select.gain_test`, one hypothesis) of replacing the
        grid term by the term at the scales each flight's own search would choose without it
        (:meth:`chosen_without`; a flight no fit trains on: ``best``)."""
        plan = self.sel.plan
        trained = np.unique(plan.cluster[~plan.held_out_only])
        choice = {int(c): (self.chosen_without(int(c)) if c in trained else best) for c in np.unique(plan.cluster)}
        distinct = sorted(set(choice.values()))
        grid = (self.kernel.width_L, self.kernel.decay_L)
        names = {at: f"{self.key}@{k}" for k, at in enumerate(distinct)}
        sums = self.sel.sums(
            {**self.others, self.key: self.column(grid), **{names[at]: self.column(at) for at in distinct}}
        )
        ridge = self.ridge_of(sums.columns)
        base = list(self.others)

        def fit(name: str) -> HeldOutFit:
            return heldout_fit(sums, sums.index([*base, name]), plan, ridge, self.sel.tau)

        fits = {at: fit(names[at]) for at in distinct}
        nested = fits[distinct[0]]
        for c, at in choice.items():
            nested = fits[at].where(plan.cluster == c, nested)
        return gain_test(sums, fit(self.key), nested, 1, cluster=plan.cluster)


def _per_train_flight(sums, fit: HeldOutFit, plan) -> np.ndarray:
    """(clusters,) each train flight's held-out squared error summed over its groups and channels (0 elsewhere)."""
    sse = np.where(np.isfinite(fit.mse), fit.mse, 0.0) * sums.w.reshape(fit.mse.shape)
    train = trainable_groups(sums, plan) > 0
    return np.bincount(plan.cluster[train], weights=sse[train].sum(axis=1), minlength=plan.n_clusters)


def refine_kernel_terms(
    sel: SelectionSet,
    fixed: Mapping[str, np.ndarray],
    kept: list[str],
    ridge_of: Callable[[tuple[str, ...]], Ridge],
) -> list[Refined]:
    """Refine each multi-scale kernel term of ``kept`` (term keys; module docstring) with the columns ``fixed``
    (name -> (N, 4), noise units: the always-fitted columns and every kept term, the one refined replaced in
    turn) fitted beside it; each later term is refined given the earlier ones' accepted refinements. Returns one
    :class:`Refined` per kernel term searched (accepted or not; a term whose best scales are its grid scales
    is not reported)."""
    targets = [(k, parse_basis_name(parse_term_key(k)[1])) for k in kept]
    if not any(p is not None for _, p in targets):
        return []
    neighbours = _Neighbours(sel)
    columns = dict(fixed)
    out: list[Refined] = []
    for key, parsed in targets:
        if parsed is None:
            continue
        kernel, axis = parsed
        search = _ScaleSearch(sel, neighbours, key, kernel, axis, {k: v for k, v in columns.items() if k != key},
                              ridge_of)  # fmt: skip
        grid = search.cost(kernel.width_L, kernel.decay_L)
        width, decay = kernel.width_L, kernel.decay_L
        for _ in range(SWEEPS):
            width = search.best_width(decay)
            decay = search.best_decay(width)
        best_at = search.rounded(width, decay)
        if best_at == search.rounded(kernel.width_L, kernel.decay_L):
            continue
        channel, feature = parse_term_key(key)
        new_key = key[: len(key) - len(feature)] + search.scaled(best_at).name(axis)
        col = search.column(best_at)  # the same feature and scaling under the refined name
        refined = Refined(new_key, key, grid, search.cost(*best_at), search.test(best_at), len(search.per_flight), col)
        out.append(refined)
        if refined.accepted:
            columns.pop(key, None)
            columns[new_key] = col
    return out


def _line(f: Callable[[float], float], centre: float, ratio: float) -> float:
    """The scale in [centre / ratio, centre x ratio] that minimises ``f``: a log-spaced scan, then golden steps."""
    logs = np.linspace(np.log(centre / ratio), np.log(centre * ratio), SCAN_POINTS)
    values = [f(float(np.exp(v))) for v in logs]
    k = int(np.argmin(values))
    lo, hi = logs[max(k - 1, 0)], logs[min(k + 1, SCAN_POINTS - 1)]
    x, fx = _golden_min(lambda v: f(float(np.exp(v))), float(lo), float(hi), GOLDEN_STEPS)
    return float(np.exp(x)) if fx < values[k] else float(np.exp(logs[k]))
