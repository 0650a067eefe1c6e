"""A kept term's scales refined off the declared grid by flights held out: a multi-scale kernel's width and decay
length, a time copy's delay or low-pass time constant (issue 35).

The dictionary holds the kernels of a neighbour above, below or beside on a coarse grid of scales
(:data:`proxplan.physics.basis.BASIS_WIDTHS_L`, ratio 2.5; :data:`~proxplan.physics.basis.BASIS_DECAYS_L`, ratio 4)
and the lagged and low-passed copies of every relative-motion feature on grids of delays
(:data:`proxplan.physics.LAGS_S`, ratio 1.5) and time constants (:data:`proxplan.physics.LOWPASS_TAUS_S`, ratio 2):
a finer grid would multiply a dictionary of ~580 features for every search. But a term fitted at the nearest
grid scale carries the train flights' coefficient to other distances with the wrong shape: the error of an
exponential decay fitted at q times the true length grows as exp(x |1 - 1/q|) with the depth x (in decay
lengths), and with q up to sqrt(4) = 2 a term fitted where two vehicles passed close is half again too strong
or too weak on a flight two decay lengths further apart (the same argument that put the ground proximity on a
fine series, stop 67; :data:`proxplan.physics.features.GROUND_SCALE_STEPS`). A delay between two of the grid's
is worse off: the selection keeps BOTH neighbours (a 0.465 s lag as lag380ms + lag570ms), two coefficients
where one effect is.

So, once discovery has KEPT a term (its hypothesis tested as before, at its grid scale), its scales are searched
continuously within one grid step of the kept scale on each side (the neighbours' territory: the grid's own
ratios, :data:`WIDTH_RATIO`, :data:`DECAY_RATIO`, :data:`LAG_RATIO`, :data:`LOWPASS_RATIO`), each in turn, by the
criterion selection uses to judge it: the error of every train flight predicted by the joint fit that did not
see it (the kept effects, the vehicle parameters' tangents and the other kept terms refitted beside it,
:func:`proxplan.identify.crossval.heldout_fit`), on the logs and channels the grid term ACTS on
(:func:`proxplan.identify.heldout_select.exposure`, as selection judges a candidate; since round 35T: summed over
every log, bench draw 36001's width search was decided by another vehicle's log, where a sibling's coefficient is
unidentified once its flight is held out and its error moved with the width only through the shared columns).
Kept SIBLINGS (one channel, one kernel or one source's copies of one kind, at other grid scales: lag380ms +
lag570ms) are searched as ONE term over the span of their brackets.

The best scales found are chosen BY those held-out errors, so their own held-out error is optimistic: searched
over ~40 scales, noise alone finds a "better" one. So each flight is judged at the scales the search would have
chosen without that flight's error (the scales tried that minimise the OTHER train flights' held-out error;
selection inside the fold, so the flight judged played no part in choosing them), by the gain test every term
passes (:func:`proxplan.identify.heldout_select.gain_test`, one hypothesis at the level
:data:`proxplan.identify.heldout_select.ALPHA`):

* one grid term: the refined term replaces it only where it passes the test against the grid term;
* several siblings: the grid terms TOGETHER must pass the test against the one refined term (nested the other
  way: the siblings are the larger model), else the one term replaces them all; where the siblings stay, each
  is refined alone as above.

No constant is set here: the level is the term test's, the brackets the grids'. A refined term is named by its
scales (``above_g0p774L_e2p31L_1``, ``above_jet_rel_speed_xy_lp283ms_mps``) and evaluated by that name
(:func:`proxplan.physics.basis.parse_basis_name`, :func:`proxplan.physics.parse_time_name`).

Search (counts, the same on every machine): per coordinate a log-spaced scan of :data:`SCAN_POINTS` points over
the bracket, then :data:`GOLDEN_STEPS` golden-section steps between the best point's neighbours; coordinate by
coordinate, :data:`SWEEPS` times where a term has two.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from typing import Protocol

import numpy as np

from proxplan.identify.crossval import HeldOutFit, Ridge, heldout_fit, trainable_groups
from proxplan.identify.design import CHANNELS, SelectionSet
from proxplan.identify.heldout_select import GainTest, fitted_exposure, gain_test
from proxplan.identify.sampled import SampledSource, UnitPart, unit_parts
from proxplan.physics import (
    BASIS_DECAYS_L,
    BASIS_WIDTHS_L,
    LAGS_S,
    LOWPASS_TAUS_S,
    BasisKernel,
    basis_columns,
    neighbour_motion,
    parse_basis_name,
    parse_term_key,
    parse_time_name,
    term_type,
    time_name,
    typed_key,
    untyped_key,
    weight_scaled,
)

__all__ = [
    "DECAY_RATIO",
    "GOLDEN_STEPS",
    "LAG_RATIO",
    "LOWPASS_RATIO",
    "SCAN_POINTS",
    "SWEEPS",
    "WIDTH_RATIO",
    "Refined",
    "refine_scaled_terms",
    "term_column",
]

WIDTH_RATIO = BASIS_WIDTHS_L[1] / BASIS_WIDTHS_L[0]
"""A width is searched within this ratio of the kept grid width on each side (the grid's own step: 2.5), -."""
DECAY_RATIO = BASIS_DECAYS_L[1] / BASIS_DECAYS_L[0]
"""A decay length is searched within this ratio of the kept grid length on each side (the grid's step: 4), -."""
LAG_RATIO = LAGS_S[1] / LAGS_S[0]
"""A delay is searched within this ratio of the kept grid delay on each side (the grid's step: 1.5), -."""
LOWPASS_RATIO = LOWPASS_TAUS_S[1] / LOWPASS_TAUS_S[0]
"""A low-pass time constant is searched within this ratio of the kept one on each side (the grid's step: 2), -."""
SCAN_POINTS = 9
"""Log-spaced points of the scan over a bracket (the kept scale its middle one): a step of ratio
ratio^(1/4) (1.26 for the width, 1.41 for the decay), the golden steps then resolve within it, -."""
GOLDEN_STEPS = 8
"""Golden-section steps within the best scan point's neighbours: the interval shrinks 0.618^8 = 0.021 times,
to a ratio under 1.01 of the scale, -."""
SWEEPS = 2
"""Passes over a term's coordinates (width, decay length): the second re-tunes each at the other's refined
value, -."""

Scales = tuple[float, ...]
"""A term's scales as its name holds them: (width L, decay length L) of a kernel, (seconds,) of a time copy."""


@dataclass(frozen=True)
class Refined:
    """One refinement: ``origin`` the grid term's key (of several siblings, the first kept), ``replaces`` every grid
    term the refined one would stand for (``(origin,)``, or the siblings where ``merged``), ``key`` the refined
    term's key (the scales searched best), the summed held-out squared error of the train flights (noise units)
    with the grid term(s) and with the refined one, ``test`` the gain test (module docstring: the refined term
    against the grid term; for siblings, the grid terms together against the one refined term), ``accepted``
    whether the refined term stands in the model (then ``key`` stands there for all of ``replaces``),
    ``evaluations`` the scales evaluated."""

    key: str
    origin: str
    heldout_grid: float
    heldout_refined: float
    test: GainTest
    evaluations: int
    column: np.ndarray = field(repr=False, compare=False)  # (N, 4) the refined term's column, noise units
    replaces: tuple[str, ...] = ()
    merged: bool = False

    @property
    def accepted(self) -> bool:
        return (not self.test.passed) if self.merged else self.test.passed

    @property
    def test_of(self) -> str:
        """What ``test`` tested (with what without what)."""
        return "grid terms together against the one refined term" if self.merged else "refined term against grid term"

    def to_json(self) -> dict[str, object]:
        return {"key": self.key, "from": self.origin, "replaces": list(self.replaces or (self.origin,)),
                "merged": self.merged, "accepted": self.accepted, "heldout_mse_grid": self.heldout_grid,
                "heldout_mse_refined": self.heldout_refined, "test": self.test.to_json(), "test_of": self.test_of,
                "evaluations": self.evaluations}  # fmt: skip


class _Neighbours:
    """Per selection sample, each neighbour's offset, size and relative velocity (full-resolution units,
    taken at the sampled rows), so a kernel at any scale is one vectorised call."""

    def __init__(self, sel: SelectionSet, parts: list[UnitPart]) -> None:
        self.parts: list[tuple[np.ndarray, float, list[tuple[np.ndarray, float, np.ndarray]]]] = []
        for part in parts:
            motion = neighbour_motion(part.inputs)
            self.parts.append((part.where, part.inputs.target.size_m,
                               [(off[part.at], size, v[part.at]) for off, size, v in motion]))  # fmt: skip
        self.n = len(sel.rows)

    def feature(self, kernel: BasisKernel, axis: str) -> np.ndarray:
        """(N,) the feature ``kernel.name(axis)`` at every selection sample."""
        out = np.zeros(self.n)
        name = kernel.name(axis)
        for where, target_size, motion in self.parts:
            for off, size, v_rel in motion:
                speed = np.hypot(v_rel[:, 0], v_rel[:, 1])
                out[where] += basis_columns(kernel, (axis,), off, size, speed, target_size)[name]
        return out


class _TermScales(Protocol):
    """A kind of scaled term: its grid scales, the ratio of its grid's step per coordinate, what its siblings
    share (``identity``), its scales as its name rounds them, its name and its values at any scales."""

    @property
    def grid(self) -> Scales: ...
    @property
    def ratios(self) -> Scales: ...
    @property
    def identity(self) -> object: ...

    def rounded(self, at: Scales) -> Scales: ...
    def name(self, at: Scales) -> str: ...
    def values(self, at: Scales) -> np.ndarray: ...


class _KernelScales:
    """A multi-scale kernel's (width L, decay length L) (:mod:`proxplan.physics.basis`)."""

    ratios: Scales = (WIDTH_RATIO, DECAY_RATIO)

    def __init__(self, neighbours: Callable[[], _Neighbours], kernel: BasisKernel, axis: str) -> None:
        self.neighbours, self.kernel, self.axis = neighbours, kernel, axis
        self.grid: Scales = (kernel.width_L, kernel.decay_L)
        self.identity: object = ("kernel", replace(kernel, width_L=0.0, decay_L=0.0), axis)

    def rounded(self, at: Scales) -> Scales:
        """The scales as the feature's name holds them (three significant digits), in L."""
        return tuple(float(f"{v:.3g}") for v in at)

    def name(self, at: Scales) -> str:
        return replace(self.kernel, width_L=at[0], decay_L=at[1]).name(self.axis)

    def values(self, at: Scales) -> np.ndarray:
        return self.neighbours().feature(replace(self.kernel, width_L=at[0], decay_L=at[1]), self.axis)


class _TimeScales:
    """A time copy's delay or low-pass time constant (s; :func:`proxplan.physics.parse_time_name`)."""

    def __init__(self, sel: SelectionSet, parts: Callable[[], list[UnitPart]], source: str, kind: str,
                 seconds: float) -> None:  # fmt: skip
        self.sel, self.parts, self.source, self.kind = sel, parts, source, kind
        self._sampled: SampledSource | None = None
        self.grid: Scales = (seconds,)
        self.ratios: Scales = (LAG_RATIO if kind == "lag" else LOWPASS_RATIO,)
        self.identity: object = ("time", source, kind)

    def rounded(self, at: Scales) -> Scales:
        """The seconds as the feature's name holds them (whole milliseconds, at least one), s."""
        return (max(1, int(round(1000.0 * at[0]))) / 1000.0,)

    def name(self, at: Scales) -> str:
        return time_name(self.source, self.kind, at[0])

    def values(self, at: Scales) -> np.ndarray:
        if self._sampled is None:  # the source at full resolution once; each copy one filter
            self._sampled = SampledSource(self.sel, self.parts(), self.source)
        return self._sampled.copy(self.kind, at[0])


def term_column(sel: SelectionSet, key: str, x: np.ndarray) -> np.ndarray:
    """(N, 4) the column of term ``key`` (noise units) from its feature's values ``x`` (N,): on its channel, scaled
    to the target where the term is weight-scaled (:func:`proxplan.physics.feature_terms.term_scale`), on the
    rows of its target type only where it names one (:func:`proxplan.physics.feature_terms.typed_key`)."""
    channel, _ = parse_term_key(key)
    c = CHANNELS.index(channel)
    col = np.zeros((len(x), len(CHANNELS)))
    scale = sel.target_scale(channel) if weight_scaled(key) else 1.0
    col[:, c] = x * scale / sel.row_scale[:, c]
    vehicle_type = term_type(key)
    if vehicle_type is not None:
        col *= (sel.target_types() == vehicle_type)[:, None]
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
    """The held-out error of one term (``key``: its name among the columns) at the scales tried: each train
    flight's summed squared error (noise units) predicted by the joint fit of the term at those scales and the
    ``others`` columns on the other train flights, memoised per scales as rounded in the name."""

    def __init__(self, sel: SelectionSet, scales: _TermScales, key: str, others: Mapping[str, np.ndarray],
                 ridge_of: Callable[[tuple[str, ...]], Ridge], grid: Mapping[str, np.ndarray]) -> None:  # fmt: skip
        self.sel, self.scales, self.key, self.others, self.ridge_of = sel, scales, key, dict(others), ridge_of
        self.per_flight: dict[Scales, np.ndarray] = {}  # scales -> (clusters,) held-out SSE
        self.acts = self.exposure(grid)  # (G, C): the cells the grid term(s) act on, where every scale is judged

    def exposure(self, columns: Mapping[str, np.ndarray]) -> np.ndarray:
        """(G, C) bool: the groups and channels where the term(s) ``columns`` (name -> (N, 4)), fitted on every
        train group beside the other columns, act (:func:`proxplan.identify.heldout_select.fitted_exposure`: the cells
        selection judges a candidate on; a log the term does not reach says nothing about its scales)."""
        sums = self.sel.sums({**self.others, **columns})
        return fitted_exposure(sums, np.arange(len(sums.columns)), sums.index(list(columns)), self.sel.plan,
                               self.ridge_of(sums.columns), self.sel.tau)  # fmt: skip

    def column(self, at: Scales) -> np.ndarray:
        """(N, 4) the term's column at the scales ``at``, noise units."""
        return term_column(self.sel, self.key, self.scales.values(at))

    def _per_flight(self, columns: Mapping[str, np.ndarray]) -> np.ndarray:
        sums = self.sel.sums({**self.others, **columns})
        fit = heldout_fit(sums, np.arange(len(sums.columns)), self.sel.plan, self.ridge_of(sums.columns),
                          self.sel.tau)  # fmt: skip
        return _per_train_flight(sums, fit, self.sel.plan, self.acts)

    def cost(self, at: Scales) -> float:
        """The summed held-out squared error of the train flights at these scales (noise units)."""
        at = self.scales.rounded(at)
        if at not in self.per_flight:
            self.per_flight[at] = self._per_flight({self.key: self.column(at)})
        return float(self.per_flight[at].sum())

    def best(self, start: Scales, lo: Scales, hi: Scales) -> Scales:
        """The scales within [lo, hi] (per coordinate) with the lowest :meth:`cost`, searched coordinate by
        coordinate from ``start``."""
        at = list(start)
        for _ in range(SWEEPS if len(at) > 1 else 1):
            for i in range(len(at)):

                def f(v: float, i: int = i) -> float:
                    return self.cost((*at[:i], v, *at[i + 1 :]))

                at[i] = _line(f, lo[i], hi[i])
        return self.scales.rounded(tuple(at))

    def chosen_without(self, cluster: int) -> Scales:
        """The scales tried that predict the train flights other than ``cluster``'s best (the choice a search
        that never saw that flight's error would make)."""
        return min(self.per_flight, key=lambda at: float(self.per_flight[at].sum() - self.per_flight[at][cluster]))

    def test(self, best: Scales, grid: Mapping[str, np.ndarray]) -> GainTest:
        """The gain test (:func:`proxplan.identify.heldout_select.gain_test`, one hypothesis) between the grid
        term(s) ``grid`` (key -> column) and the term at the scales each flight's own search would choose without
        it (:meth:`chosen_without`; a flight no fit trains on: ``best``): one grid term, the refined term against
        it; several, the grid terms together against the refined term."""
        plan = self.sel.plan
        trained = np.unique(plan.cluster[~plan.held_out_only])
        choice = {int(c): (self.chosen_without(int(c)) if c in trained else best) for c in np.unique(plan.cluster)}
        distinct = sorted(set(choice.values()))
        names = {at: f"{self.key}@{k}" for k, at in enumerate(distinct)}
        sums = self.sel.sums({**self.others, **grid, **{names[at]: self.column(at) for at in distinct}})
        ridge = self.ridge_of(sums.columns)
        base = list(self.others)

        def fit(*added: str) -> HeldOutFit:
            return heldout_fit(sums, sums.index([*base, *added]), plan, ridge, self.sel.tau)

        fits = {at: fit(names[at]) for at in distinct}
        refined = fits[distinct[0]]
        for c, at in choice.items():
            refined = fits[at].where(plan.cluster == c, refined)
        acts = self.acts | self.exposure({self.key: self.column(best)})
        if len(grid) == 1:
            return gain_test(sums, fit(*grid), refined, 1, acts, cluster=plan.cluster)
        return gain_test(sums, refined, fit(*grid), 1, acts, cluster=plan.cluster)


def _per_train_flight(sums, fit: HeldOutFit, plan, acts: np.ndarray | None = None) -> np.ndarray:
    """(clusters,) each train flight's held-out squared error summed over its groups and channels (0 elsewhere),
    over the cells ``acts`` (G, C) only where given."""
    sse = np.where(np.isfinite(fit.mse), fit.mse, 0.0) * sums.w.reshape(fit.mse.shape)
    if acts is not None:
        sse = np.where(acts, sse, 0.0)
    train = trainable_groups(sums, plan) > 0
    return np.bincount(plan.cluster[train], weights=sse[train].sum(axis=1), minlength=plan.n_clusters)


def _scales_of(sel: SelectionSet, feature: str, neighbours: Callable[[], _Neighbours],
               parts: Callable[[], list[UnitPart]]) -> _TermScales | None:  # fmt: skip
    """The scales of a kept term's feature where it has any off the grid (a kernel, a time copy), else None."""
    timed = parse_time_name(feature)
    if timed is not None:
        return _TimeScales(sel, parts, *timed)
    parsed = parse_basis_name(feature)
    return None if parsed is None else _KernelScales(neighbours, *parsed)


def _bracket(grids: list[Scales], ratios: Scales) -> tuple[Scales, Scales, Scales]:
    """(start, lo, hi) of a search over the grid scales ``grids`` (one term's, or its siblings'): one grid step
    beyond the smallest and the largest on each coordinate, started at their geometric mean."""
    g = np.log(np.array(grids))
    lo = tuple(float(np.exp(v) / r) for v, r in zip(g.min(axis=0), ratios))
    hi = tuple(float(np.exp(v) * r) for v, r in zip(g.max(axis=0), ratios))
    return tuple(float(v) for v in np.exp(g.mean(axis=0))), lo, hi


def _renamed(key: str, feature: str) -> str:
    """Term ``key`` with its feature replaced by ``feature`` (its channel, weight mark and target type kept)."""
    untyped = untyped_key(key)
    renamed = untyped[: len(untyped) - len(parse_term_key(key)[1])] + feature
    vehicle_type = term_type(key)
    return renamed if vehicle_type is None else typed_key(renamed, vehicle_type)


def _refine_one(sel: SelectionSet, key: str, scales: _TermScales, columns: Mapping[str, np.ndarray],
                ridge_of: Callable[[tuple[str, ...]], Ridge]) -> Refined | None:  # fmt: skip
    """One kept term refined within its grid step (None where its best scales are its grid scales)."""
    search = _ScaleSearch(sel, scales, key, {k: v for k, v in columns.items() if k != key}, ridge_of,
                          {key: columns[key]})  # fmt: skip
    grid = search.cost(scales.grid)
    best = search.best(*_bracket([scales.grid], scales.ratios))
    if best == scales.rounded(scales.grid):
        return None
    col = search.column(best)
    test = search.test(best, {key: columns[key]})
    return Refined(_renamed(key, scales.name(best)), key, grid, search.cost(best), test, len(search.per_flight), col,
                   (key,))  # fmt: skip


def _merge(sel: SelectionSet, members: list[str], scales: Mapping[str, _TermScales],
           columns: Mapping[str, np.ndarray], ridge_of: Callable[[tuple[str, ...]], Ridge]) -> Refined:  # fmt: skip
    """Kept siblings ``members`` searched as one term over the span of their brackets, the grid terms together
    tested against it (module docstring)."""
    first = scales[members[0]]
    others = {k: v for k, v in columns.items() if k not in members}
    grid_columns = {k: columns[k] for k in members}
    search = _ScaleSearch(sel, first, members[0], others, ridge_of, grid_columns)
    grid = float(search._per_flight(grid_columns).sum())
    best = search.best(*_bracket([scales[k].grid for k in members], first.ratios))
    col = search.column(best)
    test = search.test(best, grid_columns)
    return Refined(_renamed(members[0], first.name(best)), members[0], grid, search.cost(best), test,
                   len(search.per_flight), col, tuple(members), merged=True)  # fmt: skip


def refine_scaled_terms(
    sel: SelectionSet,
    fixed: Mapping[str, np.ndarray],
    kept: list[str],
    ridge_of: Callable[[tuple[str, ...]], Ridge],
    parts: list[UnitPart] | None = None,
) -> list[Refined]:
    """Refine each kept term of ``kept`` (term keys) that has scales off the grid (a multi-scale kernel, a time
    copy; module docstring) with the columns ``fixed`` (name -> (N, 4), noise units: the always-fitted columns and
    every kept term, the one refined replaced in turn) fitted beside it; kept siblings are first searched as one
    term, then (where the siblings stay) each alone; each later term is refined given the earlier ones' accepted
    refinements. ``parts``: the selection's :func:`proxplan.identify.sampled.unit_parts` where already built.
    Returns one :class:`Refined` per search (accepted or not; a lone term whose best scales are its grid scales
    is not reported)."""
    cache: dict[str, object] = {}

    def get_parts() -> list[UnitPart]:
        if "parts" not in cache:
            cache["parts"] = unit_parts(sel) if parts is None else parts
        return cache["parts"]  # type: ignore[return-value]

    def get_neighbours() -> _Neighbours:
        if "neighbours" not in cache:
            cache["neighbours"] = _Neighbours(sel, get_parts())
        return cache["neighbours"]  # type: ignore[return-value]

    scaled = {k: s for k in kept if (s := _scales_of(sel, parse_term_key(k)[1], get_neighbours, get_parts))}
    families: dict[tuple[str, bool, str | None, object], list[str]] = {}  # siblings: one channel, form, target type
    for k, s in scaled.items():
        families.setdefault((parse_term_key(k)[0], weight_scaled(k), term_type(k), s.identity), []).append(k)
    columns = dict(fixed)
    out: list[Refined] = []
    for members in families.values():
        if len(members) > 1:
            merged = _merge(sel, members, scaled, columns, ridge_of)
            out.append(merged)
            if merged.accepted:
                for k in members:
                    columns.pop(k, None)
                columns[merged.key] = merged.column
                continue
        for key in members:
            refined = _refine_one(sel, key, scaled[key], columns, ridge_of)
            if refined is None:
                continue
            out.append(refined)
            if refined.accepted:
                columns.pop(key, None)
                columns[refined.key] = refined.column
    return out


def _line(f: Callable[[float], float], lo: float, hi: float) -> float:
    """The scale in [lo, hi] that minimises ``f``: a log-spaced scan, then golden steps."""
    logs = np.linspace(np.log(lo), np.log(hi), SCAN_POINTS)
    values = [f(float(np.exp(v))) for v in logs]
    k = int(np.argmin(values))
    a, b = logs[max(k - 1, 0)], logs[min(k + 1, SCAN_POINTS - 1)]
    x, fx = _golden_min(lambda v: f(float(np.exp(v))), float(a), float(b), GOLDEN_STEPS)
    return float(np.exp(x)) if fx < values[k] else float(np.exp(logs[k]))
