"""A library effect read as the measurement reads the wrench, at the selection's sparse rows (issue 35).

The measured wrench is smoothed in time (:func:`proxplan.identify.measure.measure_disturbance`: the
Savitzky-Golay fit over ``window_s``, or the triangular average), so it holds S(w), not the wrench w. A
prediction compared with it must be read the same way, S(p). The base model is (once per full-rate log,
:func:`proxplan.identify.loading.smoothing_of_prediction`); this module does it for the library effects
that selection tries. Selection evaluates an effect e on its stratified rows, sparse and out of order
in time, where no filter can run, so the correction S(e) - e is evaluated on the full-rate units the rows
come from (:attr:`proxplan.identify.design.SelectionSet.sources`), smoothed on each stretch of their
clock by the measurement's own filter, and read at the rows; for an effect ``lag_s`` late it is read
``lag_s`` earlier (the filter does not depend on time, so S(e(. - L))(t) = S(e)(t - L)).

Exact for a given effect (its parameters): an effect's columns at given parameters (a linear parameter's
unit column, a fitted shape) get their own correction. While a shape is being fitted (many trial
parameters, :func:`proxplan.identify.effect_candidates.fit_shape`) the correction of the last exact
parameters of that effect is scaled to the trial's column (the least-squares factor of the trial's
column on that effect's column): exact for a change of strength, first-order for a change of shape.

Why it matters: an effect sharper in time than the window (a thrust loss with the oncoming speed SQUARED,
peaked under a jet a vehicle crosses in about 0.1 s) is flattened and widened by the measurement.
Compared unsmoothed, its exact form fits worse than a broader effect whose fitted shape mimics the
smoothing: on the closed-loop simulator's swaps with a hidden ``thrust_quadratic``, ``near_field`` was
kept in its place at the 0.15 s window in 7 of 7 replicate simulations (docs/identify.md).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from proxplan.identify.data import Model, Unit, unit_inputs
from proxplan.identify.measure import MeasureOptions, smoothed_on_clock
from proxplan.identify.noise import stacked
from proxplan.physics import BaseCache, Effect, base_cache, effect_wrench

ParamsKey = tuple[str, tuple[tuple[str, float], ...]]


def _key(effect: Effect) -> ParamsKey:
    return effect.name, tuple(sorted((k, float(v)) for k, v in effect.params.items()))


@dataclass
class MeasurementReading:
    """S(e) - e of library effects at a selection's rows (module docstring). ``sources``: the full-rate
    units; ``rows`` (N,): each row's index in their concatenation; ``row_scale`` (N, 4): the rows' noise
    units (F_z N, torques N m); ``weight`` (N,): the rows' weights; ``model``: the model the effects are
    evaluated with; ``options``: the measurement's."""

    sources: Sequence[Unit]
    rows: np.ndarray
    row_scale: np.ndarray
    weight: np.ndarray
    model: Model
    options: MeasureOptions
    _caches: list[BaseCache] | None = None
    _full: dict[str, tuple[list[np.ndarray], list[np.ndarray]]] = field(default_factory=dict)  # name -> e, S(e) - e
    _exact: dict[tuple[ParamsKey, float], np.ndarray] = field(default_factory=dict)  # (params, lag) -> at rows
    _latest: dict[str, ParamsKey] = field(default_factory=dict)  # name -> the parameters of ``_full[name]``

    def correction(self, effect: Effect, lag_s: float, columns: np.ndarray, *, exact: bool = True) -> np.ndarray:
        """(N, 4) S(e) - e at the rows, in noise units, for ``effect`` (no lag of its own) ``lag_s`` (s) late
        whose columns (N, 4, noise units, at the rows) are ``columns``; ``exact=False``: the last exact
        correction of that effect scaled to ``columns`` (module docstring)."""
        key = _key(effect)
        if exact or self._latest.get(effect.name, key) == key:
            cached = self._exact.get((key, lag_s))
            if cached is None:
                if self._latest.get(effect.name) != key:
                    self._full[effect.name] = self._full_rate(effect)
                    self._latest[effect.name] = key
                cached = self._exact[(key, lag_s)] = self._at_rows(self._full[effect.name][1], lag_s)
            return cached
        values, delta = self._full[effect.name]
        reference = self._at_rows(values, lag_s)
        w = self.weight[:, None]
        norm = float(np.sum(w * reference * reference))
        factor = float(np.sum(w * columns * reference)) / norm if norm > 0.0 else 0.0
        return factor * self._at_rows(delta, lag_s)

    def _full_rate(self, effect: Effect) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """Per source unit, e ((n, 4) N and N m) and S(e) - e on its full-rate clock."""
        if self._caches is None:
            self._caches = [base_cache(unit_inputs(u, self.model)) for u in self.sources]
        values, deltas = [], []
        for u, cache in zip(self.sources, self._caches):
            e = stacked(*effect_wrench(effect, cache.inputs, cache=cache))
            values.append(e.astype(np.float32))
            deltas.append((smoothed_on_clock(u.t_s, e, options=self.options) - e).astype(np.float32))
        return values, deltas

    def _at_rows(self, per_source: list[np.ndarray], lag_s: float) -> np.ndarray:
        """(N, 4) ``per_source`` (full-rate arrays) read at the rows' times minus ``lag_s``, in noise units
        (linear interpolation, held at a unit's first sample)."""
        starts = np.cumsum([0] + [len(u) for u in self.sources])
        src = np.searchsorted(starts, self.rows, side="right") - 1
        out = np.zeros((len(self.rows), 4))
        for k in np.unique(src):
            here = src == k
            s = self.sources[int(k)]
            idx = self.rows[here] - starts[k]
            x = per_source[int(k)]
            if lag_s == 0.0:
                out[here] = x[idx]
            else:
                t_at = s.t_s[idx] - lag_s
                out[here] = np.column_stack([np.interp(t_at, s.t_s, x[:, j]) for j in range(x.shape[1])])
        return out / self.row_scale
