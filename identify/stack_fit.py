"""Choose the stack-shielding parameter eta (:mod:`proxplan.physics.stack`) on validation flights.

eta multiplies the share of an upper source's jet that a lower source's disks and frame take out
before it reaches the target; it changes predictions only where two or more sources are above a
vehicle. It is chosen on a grid by the validation RMSE of F_z over the samples with two or more
sources overhead (r < 3 L, as :func:`proxplan.identify.evaluate.sources_overhead` counts them), so
flights with no stack leave the model's value as it is.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from proxplan.identify.data import Model, Unit, predict, sources_overhead

ETA_GRID = (0.0, 0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0)
"""Candidate values of eta (up to proxplan.physics.stack.MAX_STACK_SHIELDING), -."""
MIN_STACK_SAMPLES = 200
"""Fewer validation samples with a stack than this: eta stays at the model's value."""


@dataclass(frozen=True)
class StackChoice:
    eta: float  # chosen eta, -
    grid: tuple[float, ...]  # tried values, -
    rmse_fz_N: tuple[float, ...]  # validation RMSE of F_z on stacked samples per tried value, N
    n_samples: int  # validation samples with >= 2 sources overhead
    note: str

    def to_json(self) -> dict:
        return {"eta": self.eta, "grid": list(self.grid), "validation_rmse_fz_N": list(self.rmse_fz_N),
                "n_samples": self.n_samples, "note": self.note}  # fmt: skip


def stacked_samples(unit: Unit, model: Model) -> np.ndarray:
    """(N,) bool: two or more sources above ``unit``'s vehicle within r < 3 L of their size
    (:func:`proxplan.identify.data.sources_overhead`)."""
    return sources_overhead(unit, model.vehicles)[0] >= 2


def choose_stack_shielding(
    model: Model, valid: Sequence[Unit], *, grid: Sequence[float] = ETA_GRID
) -> tuple[Model, StackChoice]:
    """``model`` with the eta of ``grid`` that fits the validation stacks best, and the record."""
    stacked = []
    for u in valid:
        m = stacked_samples(u, model)
        if m.any():
            stacked.append(u.take(np.flatnonzero(m)))
    n = sum(len(u) for u in stacked)
    if n < MIN_STACK_SAMPLES:
        eta = model.options.stack_shielding
        return model, StackChoice(
            eta, (), (), n, f"{n} validation samples with a stack (< {MIN_STACK_SAMPLES}): eta kept at {eta:g}"
        )
    rmse = []
    for eta in grid:
        trial = replace(model, options=replace(model.options, stack_shielding=float(eta)))
        res = np.concatenate([u.force_N[:, 2] - predict(u, trial)[0][:, 2] for u in stacked])
        rmse.append(float(np.sqrt(np.mean(res**2))))
    best = float(grid[int(np.argmin(rmse))])
    chosen = replace(model, options=replace(model.options, stack_shielding=best))
    note = f"eta = {best:g} of {len(grid)} values by validation RMSE of F_z on {n} samples with >= 2 sources overhead"
    return chosen, StackChoice(best, tuple(float(g) for g in grid), tuple(rmse), n, note)
