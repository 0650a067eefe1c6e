"""The dictionary's features at a selection's samples, as discovery and the refinement of a kept term build them.

Features are computed on the full-resolution source units (lags and low-passes need the clock) at the reference
model, the sources' base wrench evaluated at :data:`BASE_RATE_HZ` and interpolated to every sample, then taken at
the selection's sampled rows. The per-unit parts (inputs, interpolated base, which rows) are built once and
reused, so :mod:`proxplan.identify.refine` can build a term's column at any scale (a kernel's width, a time
copy's delay) at the cost of that column alone.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from proxplan.identify.data import unit_inputs
from proxplan.identify.design import SelectionSet
from proxplan.physics import EffectInputs, base_wrench_per_source, feature_matrix, lagged, lowpass

__all__ = ["BASE_RATE_HZ", "SampledSource", "UnitPart", "interpolated_base", "sampled_features", "unit_parts"]

BASE_RATE_HZ = 20.0
"""Rate the sources' base wrench is evaluated at for the features, Hz, then interpolated to every sample:
it follows the vehicles' relative positions, whose motion has no content near 10 Hz (the Nyquist rate of
20 Hz), while the model call is the costliest part of the features."""


@dataclass(frozen=True)
class UnitPart:
    """One source unit's share of a selection: ``where`` (n,) the selection samples it holds, ``at`` (n,) their
    rows in the unit, its inputs at the reference model and its sources' base wrench (interpolated,
    :func:`interpolated_base`)."""

    where: np.ndarray
    at: np.ndarray
    inputs: EffectInputs
    base: list[tuple[np.ndarray, np.ndarray]]


def interpolated_base(inputs: EffectInputs) -> list[tuple[np.ndarray, np.ndarray]]:
    """Each source's base wrench (:func:`proxplan.physics.base_wrench_per_source`) evaluated every k-th sample
    (:data:`BASE_RATE_HZ`) and interpolated linearly in the sample index to every sample."""
    n = inputs.n_samples
    t = inputs.time_s
    dt = float(np.median(np.diff(t))) if t is not None and n > 1 else 0.0
    k = max(1, int(1.0 / (BASE_RATE_HZ * dt))) if dt > 0 else 1
    if k == 1 or n < 4 * k:
        return base_wrench_per_source(inputs)
    idx = np.unique(np.concatenate([np.arange(0, n, k), [n - 1]]))
    sub = replace(inputs, height_above_ground_m=np.asarray(inputs.height_above_ground_m)[idx],
                  velocity_mps=np.asarray(inputs.velocity_mps)[idx],
                  sources=tuple(replace(s, offsets_m=np.asarray(s.offsets_m)[idx],
                                        velocity_mps=None if s.velocity_mps is None else np.asarray(s.velocity_mps)[idx])
                                for s in inputs.sources),
                  time_s=None if t is None else np.asarray(t)[idx],
                  thrust_z_N=None if inputs.thrust_z_N is None else np.asarray(inputs.thrust_z_N)[idx],
                  position_m=None if inputs.position_m is None else np.asarray(inputs.position_m)[idx])  # fmt: skip
    full = np.arange(n)

    def up(a: np.ndarray) -> np.ndarray:
        return np.column_stack([np.interp(full, idx, a[:, j]) for j in range(a.shape[1])])

    return [(up(f), up(tq)) for f, tq in base_wrench_per_source(sub)]


def unit_parts(sel: SelectionSet) -> list[UnitPart]:
    """The :class:`UnitPart` of every source unit holding samples of ``sel``."""
    order = np.argsort(sel.rows, kind="stable")
    rows_sorted = sel.rows[order]
    parts = []
    start = 0
    for u in sel.sources:
        lo, hi = np.searchsorted(rows_sorted, [start, start + len(u)])
        if hi > lo:
            inputs = unit_inputs(u, sel.model)
            parts.append(UnitPart(order[lo:hi], rows_sorted[lo:hi] - start, inputs, interpolated_base(inputs)))
        start += len(u)
    return parts


def sampled_features(sel: SelectionSet, names: Sequence[str], parts: list[UnitPart] | None = None) -> np.ndarray:
    """(N, F) the features ``names`` (any :func:`proxplan.physics.is_feature`) at the selection's samples (module
    docstring); ``parts`` the selection's :func:`unit_parts` where already built."""
    out = np.zeros((len(sel.rows), len(names)))
    for part in unit_parts(sel) if parts is None else parts:
        out[part.where] = feature_matrix(part.inputs, part.base, list(names))[part.at]
    return out


class SampledSource:
    """A feature of :data:`proxplan.physics.time_copies.TIME_FEATURE_SOURCES` at full resolution on every unit part,
    computed once, so its time copy at any delay or time constant costs one filter per unit: the same values as
    :func:`sampled_features` of the copy's name (:func:`proxplan.physics.feature_matrix` filters the same source
    column with the same :func:`proxplan.physics.lagged` / :func:`proxplan.physics.lowpass`)."""

    def __init__(self, sel: SelectionSet, parts: list[UnitPart], source: str) -> None:
        self.n, self.source = len(sel.rows), source
        self.columns = [
            (part, feature_matrix(part.inputs, part.base, [source])[:, 0],
             None if part.inputs.time_s is None else np.asarray(part.inputs.time_s, dtype=float))
            for part in parts if part.inputs.sources
        ]  # fmt: skip

    def copy(self, kind: str, seconds: float) -> np.ndarray:
        """(N,) the feature ``time_name(source, kind, seconds)`` at the selection's samples."""
        out = np.zeros(self.n)
        for part, x, t in self.columns:
            out[part.where] = (lagged(x, t, seconds) if kind == "lag" else lowpass(x, t, seconds))[part.at]
        return out
