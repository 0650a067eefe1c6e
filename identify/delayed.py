"""Inputs of a delayed effect at sparse samples (issue 35: "a lag on any effect").

An effect with a delay (:data:`proxplan.physics.LAG_PARAM`) acts on the inputs of ``lag_s`` earlier. Along a
full-rate or uniformly strided log that is a shift in time (:func:`proxplan.physics.effect_wrench`), but the
fits run on stratified samples (:mod:`proxplan.identify.strata`) that are sparse and out of order in time:
no delay can be taken along them. Each sampled row therefore keeps its row in the full-rate units it was
taken from (:attr:`proxplan.identify.data.Unit.row`), and :func:`delayed_unit` interpolates every input
there at the row's time minus the delay: the exact input of the delayed effect at that row.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from proxplan.identify.data import Unit


def with_rows(units: Sequence[Unit]) -> list[Unit]:
    """``units`` (full rate, in order) with :attr:`Unit.row` set to each sample's row in their concatenation."""
    starts = np.cumsum([0] + [len(u) for u in units])
    return [replace(u, row=starts[k] + np.arange(len(u))) for k, u in enumerate(units)]


def delayed_unit(sample: Unit, sources: Sequence[Unit], lag_s: float) -> Unit:
    """``sample`` (rows of ``sources``, :attr:`Unit.row` set) with its motion, thrust and neighbours' offsets
    as they were ``lag_s`` (s) earlier: interpolated linearly on the full-rate unit each row comes from (held
    at its first sample). Its clock ``t_s`` stays the rows' own (the delayed state OF that row)."""
    assert sample.row is not None, "delayed_unit needs each sample's row in the full-rate units"
    starts = np.cumsum([0] + [len(u) for u in sources])
    src = np.searchsorted(starts, sample.row, side="right") - 1
    vel, height = sample.velocity_mps.copy(), sample.height_above_ground_m.copy()
    thrust = sample.thrust_z_N.copy()
    offsets = [o.copy() for o in sample.source_offsets_m]
    pos = None if sample.position_m is None else sample.position_m.copy()
    for k in np.unique(src):
        here = src == k
        s = sources[int(k)]
        t_at = s.t_s[sample.row[here] - starts[k]] - lag_s

        def back(x: np.ndarray, s: Unit = s, t_at: np.ndarray = t_at) -> np.ndarray:
            if x.ndim == 1:
                return np.interp(t_at, s.t_s, x)
            return np.column_stack([np.interp(t_at, s.t_s, x[:, j]) for j in range(x.shape[1])])

        vel[here], height[here], thrust[here] = back(s.velocity_mps), back(s.height_above_ground_m), back(s.thrust_z_N)
        for j, o in enumerate(s.source_offsets_m):
            offsets[j][here] = back(o)
        if pos is not None and s.position_m is not None:
            pos[here] = back(s.position_m)
    return replace(sample, velocity_mps=vel, height_above_ground_m=height, thrust_z_N=thrust,
                   source_offsets_m=tuple(offsets), position_m=pos)  # fmt: skip


def delayed_units(samples: Sequence[Unit], sources: Sequence[Unit], lags_s: Sequence[float]) -> list[dict[float, Unit]]:
    """Per sample unit, :func:`delayed_unit` at every delay of ``lags_s`` (s) above 0."""
    return [{lag: delayed_unit(u, sources, lag) for lag in lags_s if lag > 0.0} for u in samples]
