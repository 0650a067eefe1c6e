"""The linear design that effect selection and discovery run on (issue 35).

A :class:`SelectionSet` holds the samples selection sees — a stratified sample of the train flights
(:mod:`proxplan.identify.strata`) and a sample of the validation flights, each sample tagged with its
held-out group (:mod:`proxplan.identify.crossval`) — the REFERENCE model (the MAP-calibrated one, no
effects) with each unit's cached base wrench, and the residual of the reference model in noise units
per channel (:data:`CHANNELS`: world F_z and the three torques).

Columns (each (N, 4): one value per sample and channel, in the channels' noise units):

* tangent columns of the vehicle parameters (:func:`tangent_columns`): d prediction / d u, u = ln(theta)
  for a log-normal prior, u = 1 - 1/s for a thrust scale s (the coordinate the measurement is LINEAR in,
  :func:`thrust_scale_u`), theta otherwise, by a forward difference (a thrust scale's analytically); with
  their priors as a ridge
  (:func:`tangent_ridge`), so every held-out fit recalibrates too, jointly with the candidate: an
  effect the data hold is no longer absorbed into c_ax before it is tried;
* a library effect's columns (:func:`effect_columns`): its contribution per unit of its strength at its
  fitted shape;
* discovered features (:mod:`proxplan.identify.discovery`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np

from proxplan.identify.calibrate import ParamSpec, apply_vehicle_parameters, parameter_value
from proxplan.identify.crossval import GroupPlan, GroupSums, Ridge, block_ids, plan_groups
from proxplan.identify.data import Model, Unit, delayed_inputs, predict, subsample, unit_inputs
from proxplan.identify.delayed import delayed_unit
from proxplan.identify.measure import MeasureOptions
from proxplan.identify.noise import CHANNELS, NoiseLevel, stacked
from proxplan.identify.reading import MeasurementReading
from proxplan.identify.strata import stratified_sample
from proxplan.physics import BaseCache, Effect, base_cache, effect_wrench, term_scale

TANGENT_STEP = 1e-3
"""Forward-difference step of a tangent column: in ln(theta) for a log prior, in prior sigmas otherwise, -."""


@dataclass
class SelectionSet:
    """Samples, groups, reference model and residual of a selection (module docstring)."""

    units: list[Unit]
    plan: GroupPlan
    model: Model
    caches: list[BaseCache]
    measured: np.ndarray  # (N, 4) measured F_z (N) and torques (N m)
    predicted: np.ndarray  # (N, 4) the reference model's prediction
    weight: np.ndarray  # (N,) stratified weights
    group: np.ndarray  # (N,) group index
    noise: NoiseLevel  # tau and each type's noise units
    row_scale: np.ndarray  # (N, 4) each sample's noise unit per channel (N, N m)
    sources: list[Unit]  # the full-resolution units the samples come from (fit, then validation)
    rows: np.ndarray  # (N,) each sample's row in the concatenation of ``sources``
    reading: MeasurementReading | None = None  # library effects read as the measurement reads (identify.reading)

    @property
    def tau(self) -> float:
        """Integrated autocorrelation time of the residual, samples."""
        return self.noise.tau

    @property
    def residual(self) -> np.ndarray:
        """(N, 4) measured minus reference prediction, noise units."""
        return (self.measured - self.predicted) / self.row_scale

    def target_types(self) -> np.ndarray:
        """(N,) each sample's target vehicle type (object array of the type names)."""
        return np.concatenate([np.full(len(u), u.type, dtype=object) for u in self.units])

    def target_scale(self, channel: str) -> np.ndarray:
        """(N,) :func:`proxplan.physics.feature_terms.term_scale` of each sample's vehicle on ``channel`` (N or N m)."""
        return np.concatenate([np.full(len(u), term_scale(channel, self.model.vehicles[u.type])) for u in self.units])

    def offsets(self) -> list[int]:
        """Start row of each unit in the stacked arrays (and the total at the end)."""
        return list(np.cumsum([0] + [len(u) for u in self.units]))

    def sums(self, columns: Mapping[str, np.ndarray], target: np.ndarray | None = None) -> GroupSums:
        """Per-cell sums of ``columns`` (each (N, 4), noise units) against ``target`` ((N, 4), default the
        residual): every channel of every sample a row, cell = group x channel."""
        names = list(columns)
        y = self.residual if target is None else target
        x = np.stack([np.asarray(columns[k]).reshape(-1) for k in names], axis=1) if names else np.zeros((y.size, 0))
        nc = len(CHANNELS)
        cell = (self.group[:, None] * nc + np.arange(nc)[None, :]).reshape(-1)
        return GroupSums.build(x, y.reshape(-1), np.repeat(self.weight, nc), cell, self.plan.n_groups, names,
                               n_channels=nc)  # fmt: skip

    def columns_of(self, per_unit: Sequence[tuple[np.ndarray, np.ndarray]]) -> np.ndarray:
        """(N, 4) in noise units from one (force (n, 3), torque (n, 3)) wrench per unit."""
        return np.concatenate([stacked(f, t) for f, t in per_unit]) / self.row_scale


def _assign_groups(units: Sequence[Unit], plan: GroupPlan) -> list[Unit]:
    """``units`` with :attr:`Unit.group` set: the group of their (flight, vehicle), or (fallback) of their
    (block in time, vehicle)."""
    index = {n: k for k, n in enumerate(plan.names)}
    spans: dict[str, tuple[float, float]] = {}
    for u in units:
        lo, hi = spans.get(u.flight, (np.inf, -np.inf))
        spans[u.flight] = (min(lo, float(u.t_s[0])), max(hi, float(u.t_s[-1])))
    out = []
    for u in units:
        if f"{u.flight}/{u.name}" in index:
            out.append(replace(u, group=np.full(len(u), index[f"{u.flight}/{u.name}"], dtype=int)))
        else:
            blocks = block_ids(u.t_s, *spans[u.flight])
            lookup = np.array([index[f"{u.flight}#{b}/{u.name}"] for b in range(blocks.max() + 1)])
            out.append(replace(u, group=lookup[blocks]))
    return out


def selection_set(
    fit: Sequence[Unit],
    valid: Sequence[Unit],
    model: Model,
    noise: NoiseLevel,
    *,
    max_fit_samples: int,
    max_valid_samples: int,
    what: str = "selection",
    measure: MeasureOptions | None = None,
) -> SelectionSet:
    """The selection's samples (module docstring) around the reference ``model``: a stratified sample of
    ``fit`` and a uniform sample of ``valid``, grouped by :func:`proxplan.identify.crossval.plan_groups`,
    in the noise units of ``noise`` (two selections around two reference models with the same ``noise``
    compare in the same units on the same samples). ``measure``: the measurement's options, when library
    effects are to be read through its smoothing (:mod:`proxplan.identify.reading`)."""
    plan = plan_groups([(u.flight, u.name) for u in fit if len(u)], [(u.flight, u.name) for u in valid if len(u)],
                       what=what)  # fmt: skip
    sources = [u for u in fit if len(u)] + [u for u in valid if len(u)]
    starts = np.cumsum([0] + [len(u) for u in sources])
    tagged = _assign_groups([replace(u, row=starts[k] + np.arange(len(u))) for k, u in enumerate(sources)], plan)
    n_fit = sum(1 for u in fit if len(u))
    fit_g, valid_g = tagged[:n_fit], tagged[n_fit:]
    units = stratified_sample(fit_g, max_fit_samples, model.vehicles)
    if valid_g:
        units += [replace(u, weight=np.ones(len(u))) for u in subsample(valid_g, max_valid_samples)]
    units = [u for u in units if len(u)]
    caches = [base_cache(unit_inputs(u, model)) for u in units]
    predicted = np.concatenate([stacked(*predict(u, model, cache=c)) for u, c in zip(units, caches)])
    measured = np.concatenate([stacked(u.force_N, u.torque_Nm) for u in units])
    weight = np.concatenate([u.weight if u.weight is not None else np.ones(len(u)) for u in units])
    group = np.concatenate([u.group for u in units if u.group is not None]).astype(int)
    rows = np.concatenate([u.row for u in units if u.row is not None]).astype(int)
    row_scale = noise.rows(units)
    reading = None if measure is None else MeasurementReading(sources, rows, row_scale, weight, model, measure)
    return SelectionSet(units, plan, model, caches, measured, predicted, weight, group, noise, row_scale,
                        sources, rows, reading)  # fmt: skip


# ------------------------------------------------------------------------------ tangent columns


def _perturbed(model: Model, name: str, value: float) -> Model:
    vtype, key = name.rsplit(".", 1)
    if key == "stack_shielding":  # model.stack_shielding: eta of proxplan.physics.stack
        return replace(model, options=replace(model.options, stack_shielding=float(value)))
    if key == "thrust_scale":
        return replace(model, thrust_scale=dict(model.thrust_scale) | {vtype: value})
    vehicles = dict(model.vehicles)
    vehicles[vtype] = apply_vehicle_parameters(vehicles[vtype], **{key: value})
    return replace(model, vehicles=vehicles)


def tangent_columns(sel: SelectionSet, specs: Sequence[ParamSpec]) -> dict[str, np.ndarray]:
    """d prediction / d u of every parameter of ``specs`` at the reference model (module docstring), (N, 4)
    noise units each; a thrust scale's column is analytic and exact (:func:`thrust_scale_u`: d/du of
    F + u (m (g + a_z) - F) is the kinematic thrust minus the disturbance F, and F = s (prediction - u m (g
    + a_z)) at the reference's s: s times the kinematic thrust minus the prediction on F_z, minus s times
    the prediction on the torques, for its type)."""
    out: dict[str, np.ndarray] = {}
    for spec in specs:
        prior = spec.prior
        vtype, key = spec.name.rsplit(".", 1)
        if key == "thrust_scale":
            s_ref = float(parameter_value(sel.model, spec.name))
            col = np.zeros((len(sel.weight), 4))
            start = 0
            for u in sel.units:
                if u.type == vtype:
                    rows = slice(start, start + len(u))
                    kin = u.thrust_kin_z_N if u.thrust_kin_z_N is not None else sel.model.vehicles[vtype].weight_N
                    col[rows] = -s_ref * sel.predicted[rows]
                    col[rows, 0] += s_ref * kin
                start += len(u)
            out[spec.name] = col / sel.row_scale
            continue
        theta = parameter_value(sel.model, spec.name)
        if prior is not None and prior.log:
            step = TANGENT_STEP
            moved = theta * np.exp(step)
        else:
            step = TANGENT_STEP * (prior.sigma if prior is not None and prior.sigma > 0 else max(abs(theta), 1e-6))
            moved = theta + step
        m = _perturbed(sel.model, spec.name, moved)
        pred = np.concatenate([stacked(*predict(u, m)) for u in sel.units])
        out[spec.name] = (pred - sel.predicted) / step / sel.row_scale
    return out


def is_thrust_scale(spec: ParamSpec) -> bool:
    """Whether ``spec`` is a vehicle type's thrust scale s (delivered over logged thrust, -)."""
    return spec.name.endswith(".thrust_scale")


def thrust_scale_u(s: float) -> float:
    """The coordinate u = 1 - 1/s of a thrust scale s, -: the measurement reads a disturbance F as
    F / s + (1 - 1/s) m (g + a_z) (:func:`proxplan.identify.data.thrust_scaled`) = F + u (m (g + a_z) - F),
    LINEAR in u, so a step in u is exact where a step in s is not: a step of 0.046 in s from 1 reads
    0.046 m (g + a_z) linearised but 0.044 m (g + a_z) exactly, 1.3 mN on a 67 g vehicle, which the joint
    fit left as a constant offset on that type's every sample."""
    return 1.0 - 1.0 / s


def _to_u(spec: ParamSpec, theta: float) -> float:
    if is_thrust_scale(spec):
        return thrust_scale_u(theta)
    return float(np.log(theta)) if spec.prior is not None and spec.prior.log else theta


def _from_u(spec: ParamSpec, u: float) -> float:
    if is_thrust_scale(spec):
        return 1.0 / (1.0 - u)
    return float(np.exp(u)) if spec.prior is not None and spec.prior.log else u


def tangent_u(model: Model, spec: ParamSpec) -> float:
    """The coordinate u of a parameter at ``model``: ln(theta) for a log prior, 1 - 1/s for a thrust scale
    (:func:`thrust_scale_u`), theta otherwise."""
    return _to_u(spec, parameter_value(model, spec.name))


def tangent_ridge(sel: SelectionSet, specs: Sequence[ParamSpec], names: Sequence[str]) -> Ridge:
    """Ridge over ``names`` (the design's columns): the priors of the tangent columns of ``specs``
    (precision 1 / sigma_u^2, center u_prior - u_ref: the coefficient is the step from the reference);
    no prior on the other columns."""
    prec = np.zeros(len(names))
    center = np.zeros(len(names))
    pos = {n: k for k, n in enumerate(names)}
    for spec in specs:
        if spec.name not in pos or spec.prior is None or spec.prior.sigma <= 0.0:
            continue
        k = pos[spec.name]
        u_prior = _to_u(spec, spec.prior.center)
        # a thrust scale's prior N(s0, sigma) in u = 1 - 1/s: sigma du/ds = sigma / s0^2 (delta method)
        sigma_u = spec.prior.sigma / spec.prior.center**2 if is_thrust_scale(spec) else spec.prior.sigma
        prec[k] = 1.0 / sigma_u**2
        center[k] = u_prior - tangent_u(sel.model, spec)
    return Ridge(prec, center)


def apply_tangent_step(model: Model, specs: Sequence[ParamSpec], steps: Mapping[str, float]) -> Model:
    """``model`` with each parameter moved by its fitted step in u (:func:`tangent_columns`), clipped to
    its spec's bounds."""
    out = model
    for spec in specs:
        if spec.name not in steps:
            continue
        u = _to_u(spec, parameter_value(model, spec.name)) + float(steps[spec.name])
        # clipped in u (monotonic in theta): 1 - 1/s < 1 always, so a thrust scale stays positive
        u = float(np.clip(u, _to_u(spec, spec.lower), _to_u(spec, spec.upper)))
        out = _perturbed(out, spec.name, _from_u(spec, u))
    return out


# ------------------------------------------------------------------------------ effect columns


@dataclass(frozen=True)
class LagInputs:
    """The inputs a library effect ``lag_s`` (s) late is evaluated on: a :class:`proxplan.physics.BaseCache`
    per sampled unit of its state that much earlier (:func:`lag_inputs`)."""

    lag_s: float
    caches: tuple[BaseCache, ...]


def lag_inputs(sel: SelectionSet, lag_s: float) -> LagInputs:
    """:class:`LagInputs` of the delay ``lag_s`` (s): the samples' own caches at 0 (:func:`delayed_caches`)."""
    return LagInputs(lag_s, tuple(sel.caches if lag_s == 0.0 else delayed_caches(sel, lag_s)))


def effect_columns(
    sel: SelectionSet, effect: Effect, inputs: LagInputs | None = None, *, exact_reading: bool = True
) -> np.ndarray:
    """(N, 4) contribution of ``effect`` on the selection's samples (noise units), with the cached base; an
    effect with a delay (:attr:`proxplan.physics.Effect.lag_s`) on the inputs of that much earlier
    (:func:`lag_inputs`), ``inputs`` when given (those of its delay). Read as the measurement reads the
    wrench where ``sel.reading`` is set (:mod:`proxplan.identify.reading`; ``exact_reading=False`` while a
    shape is fitted: the last exact correction of the effect, scaled)."""
    if inputs is None:
        inputs = lag_inputs(sel, effect.lag_s)
    bare = effect.without_lag()
    cols = sel.columns_of([effect_wrench(bare, c.inputs, cache=c) for c in inputs.caches])
    if sel.reading is not None:
        cols = cols + sel.reading.correction(bare, inputs.lag_s, cols, exact=exact_reading)
    return cols


# ------------------------------------------------------------------------------ delayed inputs


def delayed_caches(sel: SelectionSet, lag_s: float) -> list[BaseCache]:
    """A :class:`proxplan.physics.BaseCache` per sampled unit of its inputs ``lag_s`` (s) earlier
    (:func:`proxplan.identify.delayed.delayed_unit`, on the full-rate ``sel.sources``), without a clock (each
    row its own state): the exact inputs of a delayed effect at the selection's sparse rows."""
    return [base_cache(delayed_inputs(delayed_unit(u, sel.sources, lag_s), sel.model)) for u in sel.units]
