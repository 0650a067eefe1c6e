"""Authority states of the samples and the stratified, weighted sample the fits run on.

Authority state (:func:`authority_masks`), one per sample, a partition:

* ``knocked_down`` — the vehicle's rotor plane below :data:`KNOCKED_DOWN_HEIGHT_M` with a source
  overhead (r < 3 L): pushed down by the downwash, often falling with its motors at their limits;
* ``at_limit`` — else, some motor at its floor or ceiling within +-:data:`LIMIT_NEIGHBOURHOOD_S`
  (:attr:`proxplan.identify.data.Unit.motor_limit`, :func:`proxplan.identify.thrust_map.motor_limits`);
* ``in_range`` — the rest: every motor inside its range and the vehicle not pushed down.

Stratified sample (:func:`stratified_sample`): the fits (calibration, effects) cannot afford every
train sample in every model evaluation, and a plain uniform stride leaves the rare but decisive
states (a vehicle knocked down, stacks) with a few dozen samples, so a re-run on another sample moves
the calibration. Strata are (experiment set, authority state, sources overhead 0 / 1 / 2+); each gets
its proportional share of ``max_samples``, raised to at least :data:`MIN_PER_STRATUM` (or all of its
samples when it has fewer), evenly spaced in time within the stratum. Every sampled row carries the
weight N_h / n_h (stratum size over samples taken), so weighted sums estimate the sums over the
whole train set: the objective is the pooled train error, the variance of the rare strata is lower.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from proxplan.identify.data import Unit, merge_units, sources_overhead
from proxplan.identify.manifest import set_of_flight

AUTHORITY_STATES = ("in_range", "at_limit", "knocked_down")
"""Labels of the per-authority-state report (:func:`authority_masks`), one per sample."""
LIMIT_NEIGHBOURHOOD_S = 0.2
"""A sample is ``at_limit`` when some motor of the vehicle is at its floor or ceiling within this time, s."""
KNOCKED_DOWN_HEIGHT_M = 0.25
"""``knocked_down``: rotor plane below this height above the ground with a source overhead, m (the
swaps' lowest vehicle flies at 0.35-0.45 m; below 0.25 m it has been pushed down)."""
MIN_STACK_SAMPLES = 200
"""Fewer samples with two or more sources overhead than this: the stack shielding eta is not calibrated."""
MIN_PER_STRATUM = 200
"""Each stratum of the stratified sample keeps at least this many samples (or all it has)."""


def near_in_time(t_s: np.ndarray, flag: np.ndarray, within_s: float) -> np.ndarray:
    """(N,) bool: some sample with ``flag`` (N,) lies within ``within_s`` (s) of each sample of the
    increasing clock ``t_s`` (N,)."""
    t_flag = t_s[flag]
    if t_flag.size == 0:
        return np.zeros(len(t_s), dtype=bool)
    i = np.clip(np.searchsorted(t_flag, t_s), 1, t_flag.size)  # neighbours t_flag[i-1] <= t < t_flag[i]
    before = np.abs(t_s - t_flag[i - 1])
    after = np.abs(t_flag[np.minimum(i, t_flag.size - 1)] - t_s)
    return np.minimum(before, after) <= within_s


def authority_masks(u: Unit, vehicles: Mapping[str, Any]) -> dict[str, np.ndarray]:
    """Per sample of ``u`` (one flight's clock), one mask per :data:`AUTHORITY_STATES` label (module
    docstring); logs without PWM have no known limit (never ``at_limit``)."""
    above, _ = sources_overhead(u, vehicles)
    knocked = (above > 0) & (u.height_above_ground_m < KNOCKED_DOWN_HEIGHT_M)
    if u.motor_limit is None:
        limit = np.zeros(len(u), dtype=bool)
    else:
        limit = near_in_time(u.t_s, u.motor_limit > 0, LIMIT_NEIGHBOURHOOD_S) & ~knocked
    return {"in_range": ~knocked & ~limit, "at_limit": limit, "knocked_down": knocked}


def stacked_samples(unit: Unit, vehicles: Mapping[str, Any] | Any) -> np.ndarray:
    """(N,) bool: two or more sources above ``unit``'s vehicle within r < 3 L of their size
    (:func:`proxplan.identify.data.sources_overhead`); ``vehicles`` a type mapping or a model with one."""
    return sources_overhead(unit, getattr(vehicles, "vehicles", vehicles))[0] >= 2


def stratum_labels(u: Unit, vehicles: Mapping[str, Any]) -> np.ndarray:
    """(N,) str: ``<set>|<authority state>|<sources overhead 0/1/2+>`` per sample of ``u``."""
    state = np.full(len(u), AUTHORITY_STATES[0], dtype=object)
    for name, mask in authority_masks(u, vehicles).items():
        state[mask] = name
    above = np.minimum(sources_overhead(u, vehicles)[0], 2).astype(str)
    return np.array([f"{set_of_flight(u.flight)}|{s}|{a}" for s, a in zip(state, above)], dtype=object)


def stratified_sample(units: Sequence[Unit], max_samples: int, vehicles: Mapping[str, Any]) -> list[Unit]:
    """A weighted sample of about ``max_samples`` rows of ``units`` (module docstring), merged by
    :func:`proxplan.identify.data.merge_units`; each row's :attr:`Unit.weight` is N_h / n_h. With no
    more rows than ``max_samples`` every row is kept at weight 1."""
    units = [u for u in units if len(u)]
    total = sum(len(u) for u in units)
    if total <= max_samples:
        return merge_units([replace(u, weight=np.ones(len(u))) for u in units])
    labels = [stratum_labels(u, vehicles) for u in units]
    sizes: dict[str, int] = {}
    for lab in labels:
        for k, n in zip(*np.unique(lab, return_counts=True)):
            sizes[k] = sizes.get(k, 0) + int(n)
    quota = {k: min(n, max(MIN_PER_STRATUM, int(round(max_samples * n / total)))) for k, n in sizes.items()}
    seen = dict.fromkeys(sizes, 0)  # rows of each stratum met so far, in unit / time order
    taken = []
    for u, lab in zip(units, labels):
        keep = np.zeros(len(u), dtype=bool)
        weight = np.zeros(len(u))
        for k in np.unique(lab):
            idx = np.flatnonzero(lab == k)
            # evenly spaced over the stratum's rows: row j of the stratum is taken when it starts a new
            # 1/quota share of them
            j = seen[k] + np.arange(len(idx))
            pick = np.floor((j + 1) * quota[k] / sizes[k]) > np.floor(j * quota[k] / sizes[k])
            keep[idx[pick]] = True
            weight[idx[pick]] = sizes[k] / quota[k]
            seen[k] += len(idx)
        sel = np.flatnonzero(keep)
        taken.append(replace(u.take(sel), weight=weight[sel]))
    return merge_units(taken)
