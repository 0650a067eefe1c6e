"""Terms no library effect names: sparse regression of the residual on a physical feature dictionary.

After the library effects are selected (:mod:`proxplan.identify.effect_selection`), the residual of the
current model (measured minus predicted wrench) is regressed, channel by channel (world F_z and the
three torques), on the features of :mod:`proxplan.physics.features` (neighbours above and below, relative
velocities, the base prediction and its lagged / low-pass copies, height above ground, own speed and
thrust). The regression is scikit-learn's Orthogonal Matching Pursuit on RMS-scaled columns, fitted
on TRAIN units only, for 1..``max_terms`` terms; the VALIDATION units choose the number of terms
(the smallest within ``tolerance`` of the best validation RMSE).

A term is kept only if it lowers that channel's VALIDATION RMSE by at least ``min_gain`` (relative,
default 10 %) AND by at least :data:`MIN_IMPROVEMENT` (absolute: 0.1 g of force, 2e-5 N m of torque):
clean data (residual = noise) gives gains near zero and nothing is kept, and a real but tiny
structure (e.g. 1e-5 N m of roll torque the closed-loop measurement does not resolve) is reported
but not kept. Test units, when given, only report. The kept terms of all channels form ONE effect
``Effect("discovered:residual", {"<channel>*<feature>": coefficient})`` (coefficients in channel
units per feature unit; one effect so the base wrench it needs is computed once), which
:mod:`proxplan.physics.effects` applies like any effect (pairwise features make it act between vehicles),
and which a saved model stores as name + params.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from sklearn.linear_model import OrthogonalMatchingPursuit

from proxplan.identify.data import Model, Unit, predict, unit_inputs
from proxplan.physics import (
    CHANNELS,
    DISCOVERED_PREFIX,
    FEATURE_NAMES,
    Effect,
    base_wrench_per_source,
    feature_matrix,
    term_formula,
)

DISCOVERED_NAME = f"{DISCOVERED_PREFIX}residual"
"""Name of the one effect holding every kept term."""

CHANNEL_COLUMNS = {"force_z_N": 2, "torque_x_Nm": 3, "torque_y_Nm": 4, "torque_z_Nm": 5}
"""Channels searched by default and their column in the stacked (force, torque) wrench (N, 6)."""


@dataclass(frozen=True)
class DiscoveryOptions:
    """How terms are searched and when one is kept."""

    channels: tuple[str, ...] = tuple(CHANNEL_COLUMNS)
    max_terms: int = 4  # at most this many features per channel, -
    min_gain: float = 0.10  # relative cut of the channel's VALIDATION RMSE a term must bring, -
    tolerance: float = 0.02  # fewest terms within this relative margin of the best validation RMSE, -
    max_fit_samples: int = 20000  # train rows of the regression (uniform stride after features), -
    min_improvement: dict[str, float] | None = None  # per channel, absolute validation RMSE cut; None: default


MIN_IMPROVEMENT = {"force_z_N": 1e-3, "torque_x_Nm": 2e-5, "torque_y_Nm": 2e-5, "torque_z_Nm": 2e-5}
"""Smallest absolute cut of a channel's validation RMSE worth a term: 1e-3 N (0.1 g) of force and
2e-5 N m (0.1 g at a 2 cm arm) of torque. Below that a structure is real but irrelevant to a plan."""


@dataclass(frozen=True)
class _Rows:
    features: np.ndarray  # (N, F)
    residual: np.ndarray  # (N, 6) measured minus predicted (force, torque)


def _rows(units: Sequence[Unit], model: Model, max_rows: int | None = None) -> _Rows:
    """Features and residual of every unit at full resolution (time features need the clock), then
    an optional uniform stride down to ``max_rows``."""
    xs, rs = [], []
    for u in units:
        if not len(u):
            continue
        inputs = unit_inputs(u, model)
        per_source = base_wrench_per_source(inputs)  # shielded in stacks, as predict's base
        base_f = sum((p[0] for p in per_source), np.zeros((len(u), 3)))
        base_t = sum((p[1] for p in per_source), np.zeros((len(u), 3)))
        pf, pt = predict(u, model, base=(base_f, base_t))
        xs.append(feature_matrix(inputs, per_source))
        rs.append(np.column_stack([u.force_N - pf, u.torque_Nm - pt]))
    x = np.concatenate(xs) if xs else np.zeros((0, len(FEATURE_NAMES)))
    r = np.concatenate(rs) if rs else np.zeros((0, 6))
    if max_rows is not None and len(x) > max_rows:
        idx = np.arange(0, len(x), int(np.ceil(len(x) / max_rows)))
        x, r = x[idx], r[idx]
    return _Rows(x, r)


def _rmse(r: np.ndarray) -> float:
    return float(np.sqrt(np.mean(r**2))) if len(r) else float("nan")


@dataclass(frozen=True)
class ChannelFit:
    channel: str
    params: dict[str, float]  # "<channel>*<feature>" -> coefficient (channel unit per feature unit)
    rmse_validation_before: float
    rmse_validation_after: float
    n_terms_tried: int

    @property
    def gain(self) -> float:
        if not np.isfinite(self.rmse_validation_before) or self.rmse_validation_before <= 0.0:
            return 0.0
        return 1.0 - self.rmse_validation_after / self.rmse_validation_before


def fit_channel(channel: str, train: _Rows, validation: _Rows, options: DiscoveryOptions) -> ChannelFit:
    """OMP path on train for 1..max_terms; the validation RMSE picks the number of terms."""
    col = CHANNELS.index(channel)
    y, yv = train.residual[:, col], validation.residual[:, col]
    before = _rmse(yv)
    scale = np.sqrt(np.mean(train.features**2, axis=0))
    usable = np.flatnonzero((scale > 1e-12) & np.all(np.isfinite(train.features), axis=0))
    if len(usable) == 0 or len(y) < 10 or len(yv) < 10 or _rmse(y) <= 0.0:
        return ChannelFit(channel, {}, before, before, 0)
    xs = train.features[:, usable] / scale[usable]
    xv = validation.features[:, usable] / scale[usable]
    path: list[tuple[float, np.ndarray]] = []
    for k in range(1, min(options.max_terms, len(usable)) + 1):
        with warnings.catch_warnings():  # collinear features (e.g. no clock: lagged == base) stop OMP early
            warnings.filterwarnings("ignore", message="Orthogonal matching pursuit ended prematurely")
            omp = OrthogonalMatchingPursuit(n_nonzero_coefs=k, fit_intercept=False).fit(xs, y)
        path.append((_rmse(yv - xv @ omp.coef_), omp.coef_.copy()))
    best = min(e for e, _ in path)
    err, coef = next((e, c) for e, c in path if e <= best * (1.0 + options.tolerance))
    params = {f"{channel}*{FEATURE_NAMES[usable[j]]}": float(coef[j] / scale[usable[j]]) for j in np.flatnonzero(coef)}
    return ChannelFit(channel, params, before, err, len(path))


def discover_terms(
    train: Sequence[Unit],
    validation: Sequence[Unit],
    model: Model,
    *,
    test: Sequence[Unit] = (),
    options: DiscoveryOptions = DiscoveryOptions(),
) -> tuple[Model, list[dict[str, Any]]]:
    """Search every channel of ``options.channels`` for a term the model lacks (module docstring).

    Returns the model with the kept terms appended to its effects (one effect,
    :data:`DISCOVERED_NAME`) and one JSON entry per channel
    searched: ``{"name", "formula", "features", "params", "rmse_fz_N", "selected", "channel",
    "gain_validation", "rmse_validation": {"before", "after"}, "rmse_test": {"before", "after"}}``;
    ``rmse_fz_N`` is the F_z RMSE with the term on test units (validation units when no test is given).
    """
    tr = _rows(train, model, options.max_fit_samples)
    va = _rows(validation, model)
    te = _rows(test, model) if len(test) else va
    kept: dict[str, float] = {}
    report = []
    for channel in options.channels:
        fit = fit_channel(channel, tr, va, options)
        least = (options.min_improvement or MIN_IMPROVEMENT).get(channel, 0.0)
        cut = fit.rmse_validation_before - fit.rmse_validation_after
        selected = bool(fit.params) and fit.gain >= options.min_gain and cut >= least
        eff = Effect(DISCOVERED_NAME, fit.params)
        col = CHANNELS.index(channel)
        x_te = te.features
        term_te = x_te[:, [FEATURE_NAMES.index(f) for f in eff.features]] @ np.array(list(fit.params.values()))
        fz_after = te.residual[:, 2] - (term_te if channel == "force_z_N" and fit.params else 0.0)
        if selected:
            kept.update(fit.params)
        report.append({
            "name": eff.name, "channel": channel, "formula": term_formula(fit.params) if fit.params else "",
            "features": list(eff.features), "params": dict(fit.params), "rmse_fz_N": _rmse(fz_after),
            "gain_validation": fit.gain,
            "rmse_validation": {"before": fit.rmse_validation_before, "after": fit.rmse_validation_after},
            "rmse_test": {"before": _rmse(te.residual[:, col]),
                          "after": _rmse(te.residual[:, col] - (term_te if fit.params else 0.0))},
            "selected": selected,
        })  # fmt: skip
    extra = (Effect(DISCOVERED_NAME, kept),) if kept else ()
    return replace(model, effects=tuple(model.effects) + extra), report
