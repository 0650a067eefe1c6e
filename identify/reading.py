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

from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from proxplan.identify.data import Model, Unit, unit_inputs
from proxplan.identify.measure import MeasureOptions, smoothed_on_clock
from proxplan.identify.noise import stacked
from proxplan.physics import BaseCache, Effect, base_cache, effect_wrench

ParamsKey = tuple[str, tuple[tuple[str, float], ...]]

KEPT_FULL_RATE = 8
"""Full-rate evaluations kept (the latest), -: a linear effect's unit columns (up to 3) and a shape's probes
(2) are asked for in turn at every delay; each costs 2 x 4 float32 per full-rate sample (13 MB at 400 000)."""


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
    # parameters -> per source e, S(e) - e at full rate (the KEPT_FULL_RATE latest; a linear effect's unit
    # columns are profiled over the delays together, so each is asked for at every delay in turn)
    _full: OrderedDict[ParamsKey, tuple[np.ndarray, np.ndarray]] = field(default_factory=OrderedDict)
    # (params, delay) -> e and S(e) - e at the rows (noise units)
    _read: dict[tuple[ParamsKey, float], tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)
    _latest: dict[str, ParamsKey] = field(default_factory=dict)  # name -> its last exact parameters
    _taps: dict[float, tuple[np.ndarray, np.ndarray, np.ndarray]] = field(default_factory=dict)  # delay -> i0, i1, f

    def correction(self, effect: Effect, lag_s: float, columns: np.ndarray, *, exact: bool = True) -> np.ndarray:
        """(N, 4) S(e) - e at the rows, in noise units, for ``effect`` (no lag of its own) ``lag_s`` (s) late
        whose columns (N, 4, noise units, at the rows) are ``columns``; ``exact=False``: the last exact
        correction of that effect scaled to ``columns`` (module docstring)."""
        key = _key(effect)
        if exact or effect.name not in self._latest:
            self._latest[effect.name] = key
        if self._latest[effect.name] == key:
            return self._at(key, effect, lag_s)[1]
        reference, delta = self._at(self._latest[effect.name], effect, lag_s)
        w = self.weight[:, None]
        norm = float(np.sum(w * reference * reference))
        factor = float(np.sum(w * columns * reference)) / norm if norm > 0.0 else 0.0
        return factor * delta

    def _at(self, key: ParamsKey, effect: Effect, lag_s: float) -> tuple[np.ndarray, np.ndarray]:
        """e and S(e) - e ((N, 4) each, noise units) of the parameters ``key`` at the rows, ``lag_s`` (s) late."""
        out = self._read.get((key, lag_s))
        if out is None:
            values, delta = self._full_rate(key, effect)
            out = self._read[(key, lag_s)] = (self._at_rows(values, lag_s), self._at_rows(delta, lag_s))
        return out

    def _full_rate(self, key: ParamsKey, effect: Effect) -> tuple[np.ndarray, np.ndarray]:
        """e ((n, 4) N and N m) and S(e) - e on the sources' full-rate clocks (concatenated), of the effect of parameters
        ``key`` (``effect``'s name, ``key``'s parameters; kept for the :data:`KEPT_FULL_RATE` latest)."""
        if key in self._full:
            self._full.move_to_end(key)
            return self._full[key]
        effect = Effect(effect.name, dict(key[1]))
        if self._caches is None:
            self._caches = [base_cache(unit_inputs(u, self.model)) for u in self.sources]
        values, deltas = [], []
        for u, cache in zip(self.sources, self._caches):
            e = stacked(*effect_wrench(effect, cache.inputs, cache=cache))
            values.append(e.astype(np.float32))
            deltas.append((smoothed_on_clock(u.t_s, e, options=self.options) - e).astype(np.float32))
        self._full[key] = out = (np.concatenate(values), np.concatenate(deltas))
        while len(self._full) > KEPT_FULL_RATE:
            self._full.popitem(last=False)
        return out

    def _at_rows(self, flat: np.ndarray, lag_s: float) -> np.ndarray:
        """(N, 4) ``flat`` (full-rate, the sources concatenated) read at the rows' times minus ``lag_s`` (s), in
        noise units (linear interpolation on each source's clock, held at its ends, as ``np.interp``)."""
        if lag_s == 0.0:
            return flat[self.rows] / self.row_scale
        if lag_s not in self._taps:
            self._taps[lag_s] = self._interpolation(lag_s)
        i0, i1, f = self._taps[lag_s]
        return (flat[i0] * (1.0 - f)[:, None] + flat[i1] * f[:, None]) / self.row_scale

    def _interpolation(self, lag_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Flat indices i0, i1 (N,) and weights f (N,) with x(t_row - ``lag_s``) = (1 - f) x[i0] + f x[i1]."""
        starts = np.cumsum([0] + [len(u) for u in self.sources])
        src = np.searchsorted(starts, self.rows, side="right") - 1
        i0, i1, f = self.rows.copy(), self.rows.copy(), np.zeros(len(self.rows))
        for k in np.unique(src):
            here = src == k
            t = self.sources[int(k)].t_s
            if len(t) < 2:
                continue
            t_at = np.clip(t[self.rows[here] - starts[k]] - lag_s, t[0], t[-1])
            j = np.clip(np.searchsorted(t, t_at, side="right") - 1, 0, len(t) - 2)
            i0[here], i1[here] = starts[k] + j, starts[k] + j + 1
            f[here] = np.clip((t_at - t[j]) / (t[j + 1] - t[j]), 0.0, 1.0)
        return i0, i1, f
