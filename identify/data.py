"""Samples, models and errors of the identification pipeline (:mod:`proxplan.identify.pipeline`).

A :class:`Unit` is one vehicle of one flight: its measured disturbance (S0-11, S0-13) and the
logged relative positions of the other vehicles; a :class:`Model` is the vehicles plus effects
and thrust scales that predict it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from proxplan.identify.measure import MeasureOptions
from proxplan.physics import (
    EFFECT_NAMES,
    VALIDITY_FACTOR_L,
    BaseCache,
    Effect,
    EffectInputs,
    ModelOptions,
    SourceSample,
    Vehicle,
    base_cache,
    base_wrench,
    effect_wrench,
)


@dataclass(frozen=True)
class IdentifyOptions:
    """Options of the identification pipeline."""

    measure: MeasureOptions = MeasureOptions()
    field_form: str = "inverse-z"  # form of (S0-1) used for prediction
    calibrate: bool = True
    effects: tuple[str, ...] = EFFECT_NAMES  # candidates to try
    max_fit_samples: int = 10000  # train samples of the calibration and the selection (stratified sample)
    max_eval_samples: int = 10000  # validation samples of the selection; test samples per candidate report
    progress: bool = False  # tqdm bars on stderr
    discover: bool = True  # search terms no library effect names (proxplan.identify.discovery)
    stack_shielding: float = (
        1.0  # eta the calibration starts from (proxplan.physics.stack), -; then chosen on validation
    )
    smoothed_prediction: bool = (
        True  # predictions read through the measurement's smoothing (loading.smoothing_of_prediction)
    )
    workers: int = 1  # processes, -: above 1, independent stages run beside each other (pipeline.run_identify)


CEILING_BIT, FLOOR_BIT = 1, 2
"""Bits of :attr:`Unit.motor_limit`: some motor of the vehicle at its ceiling / at its floor
(:func:`proxplan.identify.thrust_map.motor_limits`)."""


@dataclass(frozen=True)
class Unit:
    """One vehicle of one flight, N cleaned samples, ready for prediction."""

    flight: str
    split: str
    name: str  # vehicle name in the flight (e.g. cf51)
    type: str  # vehicle type
    t_s: np.ndarray  # (N,) own clock, s
    velocity_mps: np.ndarray  # (N, 3) world
    height_above_ground_m: np.ndarray  # (N,)
    thrust_z_N: np.ndarray  # (N,) sum of logged motor thrusts times (z_B)_z, N
    source_types: tuple[str, ...]
    source_offsets_m: tuple[np.ndarray, ...]  # each (N, 3) p_target - p_source, world
    force_N: np.ndarray  # (N, 3) measured, world
    torque_Nm: np.ndarray  # (N, 3) measured, world
    thrust: Any = None  # proxplan.identify.thrust_rls.ThrustSamples of the full unit (None after take)
    scored: bool = True  # False: manifest 'score: false' (a downwash source only, never scored or fitted)
    position_m: np.ndarray | None = None  # (N, 3) own position, world frame (the log's), m
    planes: tuple = ()  # proxplan.physics.room.Plane of the manifest (place-in-room features)
    motor_limit: np.ndarray | None = None  # (N,) uint8 bits: CEILING_BIT / FLOOR_BIT, some motor at that limit
    weight: np.ndarray | None = None  # (N,) sampling weight of a stratified sample (identify.strata), -
    group: np.ndarray | None = None  # (N,) int: held-out group of each sample (proxplan.identify.crossval)
    row: np.ndarray | None = None  # (N,) int: each sample's row in the full-resolution units it was sampled from
    thrust_kin_z_N: np.ndarray | None = None  # (N,) m (g + dv_z/dt) from the motion (measure.kinematic_thrust_z_N), N
    # what the measurement's smoothing does to the prior model's wrench, S(p) - p (force (N, 3) N, torque (N, 3)
    # N m, world; proxplan.identify.loading.smoothing_of_prediction): added to every prediction (predict)
    smoothing_force_N: np.ndarray | None = None
    smoothing_torque_Nm: np.ndarray | None = None

    def take(self, idx: np.ndarray) -> Unit:
        return replace(
            self,
            position_m=None if self.position_m is None else self.position_m[idx],
            motor_limit=None if self.motor_limit is None else self.motor_limit[idx],
            weight=None if self.weight is None else self.weight[idx],
            group=None if self.group is None else self.group[idx],
            row=None if self.row is None else self.row[idx],
            thrust_kin_z_N=None if self.thrust_kin_z_N is None else self.thrust_kin_z_N[idx],
            smoothing_force_N=None if self.smoothing_force_N is None else self.smoothing_force_N[idx],
            smoothing_torque_Nm=None if self.smoothing_torque_Nm is None else self.smoothing_torque_Nm[idx],
            t_s=self.t_s[idx],
            velocity_mps=self.velocity_mps[idx],
            height_above_ground_m=self.height_above_ground_m[idx],
            thrust_z_N=self.thrust_z_N[idx],
            source_offsets_m=tuple(o[idx] for o in self.source_offsets_m),
            force_N=self.force_N[idx],
            torque_Nm=self.torque_Nm[idx],
            thrust=None,
        )

    def __len__(self) -> int:
        return len(self.t_s)


@dataclass(frozen=True)
class Model:
    """Vehicles by type, per-type thrust scales and effects: everything a prediction needs."""

    vehicles: Mapping[str, Vehicle]
    thrust_scale: Mapping[str, float] = field(default_factory=dict)
    effects: tuple[Effect, ...] = ()
    options: ModelOptions = ModelOptions()


def unit_inputs(unit: Unit, model: Model) -> EffectInputs:
    return EffectInputs(
        target=model.vehicles[unit.type],
        height_above_ground_m=unit.height_above_ground_m,
        velocity_mps=unit.velocity_mps,
        sources=tuple(SourceSample(model.vehicles[t], o) for t, o in zip(unit.source_types, unit.source_offsets_m)),
        options=model.options,
        time_s=unit.t_s,
        thrust_z_N=unit.thrust_z_N,
        position_m=unit.position_m,
        planes=unit.planes,
    )


def delayed_inputs(unit: Unit, model: Model) -> EffectInputs:
    """The effect inputs of a delayed copy of a unit (:func:`proxplan.identify.delayed.delayed_unit`): no
    clock, each row the state of its own delay."""
    return replace(unit_inputs(unit, model), time_s=None)


def predict(
    unit: Unit,
    model: Model,
    *,
    base: tuple[np.ndarray, np.ndarray] | None = None,
    cache: BaseCache | None = None,
    delayed: Mapping[float, Unit] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Predicted measured wrench (force (N, 3) N, torque (N, 3) N m, world) of ``unit``: the model's wrench plus
    what the measurement's smoothing does to it (:attr:`Unit.smoothing_force_N`, :attr:`Unit.smoothing_torque_Nm`,
    when the unit has them), as the measurement reads it (:func:`thrust_scaled`; the smoothing's part is read
    through the thrust scale too, so a thrust scale's analytic column stays exact).

    ``base`` may pass a precomputed base wrench for the same vehicles (saves the model call), and
    ``cache`` the :class:`proxplan.physics.BaseCache` of ``unit_inputs(unit, model)`` (the sources' base
    wrenches the effects reuse). ``delayed`` (delay s -> the unit's state that much earlier,
    :func:`proxplan.identify.delayed.delayed_unit`) is where a delayed effect is evaluated at a sparse sample;
    without it the delay is taken along the unit's clock (a full-rate or strided log).
    """
    inputs = cache.inputs if cache is not None else unit_inputs(unit, model)
    if base is not None:
        force, torque = base[0].copy(), base[1].copy()
    elif cache is not None:
        force, torque = np.zeros((len(unit), 3)), np.zeros((len(unit), 3))
        for f, t in cache.per_source():
            force += f
            torque += t
    else:
        force, torque = base_wrench(inputs)
    for eff in model.effects:
        if delayed is not None and eff.lag_s > 0.0:
            f, t = effect_wrench(eff.without_lag(), delayed_inputs(delayed[eff.lag_s], model))
        else:
            f, t = effect_wrench(eff, inputs, cache=cache)
        force += f
        torque += t
    if unit.smoothing_force_N is not None and unit.smoothing_torque_Nm is not None:
        # the measurement smooths what it reads, and it reads the smoothed wrench through the thrust scale
        # like the rest: S(F / s + u m (g + a_z)) = (F + S(F) - F) / s + u m (g + a_z) (the kinematic thrust is
        # taken from the smoothed motion already)
        force, torque = force + unit.smoothing_force_N, torque + unit.smoothing_torque_Nm
    return thrust_scaled(force, torque, model.thrust_scale.get(unit.type, 1.0), unit, model)


def thrust_scaled(
    force: np.ndarray, torque: np.ndarray, s: float, unit: Unit, model: Model
) -> tuple[np.ndarray, np.ndarray]:
    """What the measurement reads of a disturbance ``force`` (N, 3) N, ``torque`` (N, 3) N m when the motors
    deliver s times the logged thrust (a thrust-map error of their type).

    With the logged thrust T_log = T / s in (S0-11) and the motion's m (g + a_z) = T + F_z (the thrust the
    motion calls for, :attr:`Unit.thrust_kin_z_N`), the measured force is F_z + (s - 1) T_log =
    F_z / s + ((s - 1) / s) m (g + a_z); in (S0-13) the motors' torque cancels the disturbance's in steady
    flight, so the measured torque is tau / s. Written with the kinematic thrust, not the logged one: the
    logged thrust's noise also sits in the measured force, and a scale fitted on it comes out biased (by
    about 0.2 var(noise) / var(thrust): 0.6 % for a Crazyflie, a 2 mN offset that other terms then absorb)."""
    if s == 1.0:
        return force, torque
    kin = (
        unit.thrust_kin_z_N
        if unit.thrust_kin_z_N is not None
        else np.full(len(unit), model.vehicles[unit.type].weight_N)
    )
    force = force / s
    force[:, 2] += (s - 1.0) / s * kin
    return force, torque / s


def progress_bar(items: Sequence, desc: str, enabled: bool):
    if not enabled:
        return items
    from tqdm import tqdm

    return tqdm(items, desc=desc, unit="item", leave=False)


def merge_units(units: Sequence[Unit]) -> list[Unit]:
    """Concatenate units that share target type and source types (one model call per group).

    The result is for pooled errors and fits only: its ``t_s`` is not monotonic."""
    groups: dict[tuple, list[Unit]] = {}
    for u in units:
        if len(u):
            groups.setdefault((u.split, u.type, u.source_types), []).append(u)
    out = []
    for (split, vtype, stypes), us in groups.items():
        if len(us) == 1:
            out.append(us[0])
            continue

        def cat(key: str, us: list = us) -> np.ndarray:
            return np.concatenate([getattr(u, key) for u in us])

        out.append(Unit(
            flight="+".join(u.flight for u in us), split=split, name="+".join(u.name for u in us), type=vtype,
            t_s=cat("t_s"), velocity_mps=cat("velocity_mps"), height_above_ground_m=cat("height_above_ground_m"),
            thrust_z_N=cat("thrust_z_N"), source_types=stypes,
            source_offsets_m=tuple(np.concatenate([u.source_offsets_m[k] for u in us]) for k in range(len(stypes))),
            force_N=cat("force_N"), torque_Nm=cat("torque_Nm"),
            position_m=None if any(u.position_m is None for u in us) else cat("position_m"),
            planes=us[0].planes if all(u.planes == us[0].planes for u in us) else (),
            motor_limit=None if any(u.motor_limit is None for u in us) else cat("motor_limit"),
            weight=None if any(u.weight is None for u in us) else cat("weight"),
            group=None if any(u.group is None for u in us) else cat("group"),
            row=None if any(u.row is None for u in us) else cat("row"),
            thrust_kin_z_N=None if any(u.thrust_kin_z_N is None for u in us) else cat("thrust_kin_z_N"),
            smoothing_force_N=None if any(u.smoothing_force_N is None for u in us) else cat("smoothing_force_N"),
            smoothing_torque_Nm=None if any(u.smoothing_torque_Nm is None for u in us) else cat("smoothing_torque_Nm"),
        ))  # fmt: skip
    return out


NEIGHBOUR_REACH_L = 3.0
"""A source overhead counts within this many of its sizes L off the target's vertical axis (r < 3 L): the jet's
edge of (S0-1, S0-2) at the separations flown, -; :func:`neighbours_near` takes the same reach in any direction."""


def sources_overhead(u: Unit, vehicles: Mapping[str, Any]) -> tuple[np.ndarray, np.ndarray]:
    """Per sample of ``u``: the number of sources above within r < 3 L (N,) int (:data:`NEIGHBOUR_REACH_L`), and
    whether one of them is closer than dz < 3 L (N,) bool."""
    n = len(u)
    above = np.zeros(n, dtype=int)
    near = np.zeros(n, dtype=bool)
    for t, off in zip(u.source_types, u.source_offsets_m):
        L = vehicles[t].size_m
        dz, r = -off[:, 2], np.hypot(off[:, 0], off[:, 1])
        here = (dz > 0.0) & (r < NEIGHBOUR_REACH_L * L)
        above += here
        near |= here & (dz < VALIDITY_FACTOR_L * L)
    return above, near


def neighbours_near(u: Unit, vehicles: Mapping[str, Any]) -> np.ndarray:
    """Per sample of ``u`` (N,) bool: some other vehicle of the flight, above, beside or below, lies within
    :data:`NEIGHBOUR_REACH_L` times the larger of its and the target's size L (3-D distance, m over m). Its
    complement, with no source overhead, is a vehicle flying ALONE: no neighbour's air, known or not, is near."""
    near = np.zeros(len(u), dtype=bool)
    own_L = vehicles[u.type].size_m
    for t, off in zip(u.source_types, u.source_offsets_m):
        near |= np.linalg.norm(off, axis=1) < NEIGHBOUR_REACH_L * max(vehicles[t].size_m, own_L)
    return near


def subsample(units: Sequence[Unit], max_samples: int) -> list[Unit]:
    """Uniform-stride subsample of ``units`` keeping at most ``max_samples`` samples in total,
    merged by :func:`merge_units`."""
    total = sum(len(u) for u in units)
    stride = max(1, int(np.ceil(total / max(max_samples, 1))))
    return merge_units([u.take(np.arange(0, len(u), stride)) for u in units if len(u)])


# ------------------------------------------------------------------------------ errors


@dataclass(frozen=True)
class Errors:
    rmse_fz_N: float
    rmse_torque_Nm: float  # RMS of the torque error vector norm
    rmse_tz_Nm: float  # yaw torque
    n_samples: int

    def to_json(self) -> dict[str, float]:
        return {
            "rmse_fz_N": self.rmse_fz_N,
            "rmse_torque_Nm": self.rmse_torque_Nm,
            "rmse_tz_Nm": self.rmse_tz_Nm,
            "n_samples": self.n_samples,
        }


class Predictions:
    """Predictions of models on units where each (unit, vehicles, options) pair evaluates the base model once:
    its sources' base wrench (:class:`proxplan.physics.BaseCache`) is kept and reused by every effect and
    every later call (the report scores the same test samples many ways)."""

    def __init__(self) -> None:
        self._caches: dict[tuple[int, int, ModelOptions], tuple[Unit, Any, BaseCache]] = {}

    def cache(self, unit: Unit, model: Model) -> BaseCache:
        key = (id(unit), id(model.vehicles), model.options)
        if key not in self._caches:  # the unit and the vehicles are kept alive with their cache
            self._caches[key] = (unit, model.vehicles, base_cache(unit_inputs(unit, model)))
        return self._caches[key][2]

    def __call__(self, unit: Unit, model: Model) -> tuple[np.ndarray, np.ndarray]:
        return predict(unit, model, cache=self.cache(unit, model))


def rmse_fz_by_vehicle(
    units: Sequence[Unit], model: Model, predictions: Predictions | None = None
) -> dict[str, tuple[float, int]]:
    """Pooled RMSE of F_z (N) and sample count per vehicle name (the manifest's key) over ``units``."""
    sse: dict[str, list[float]] = {}
    for u in units:
        r = u.force_N[:, 2] - (predictions(u, model) if predictions is not None else predict(u, model))[0][:, 2]
        acc = sse.setdefault(u.name, [0.0, 0.0])
        acc[0] += float(r @ r)
        acc[1] += r.size
    return {k: (float(np.sqrt(a / n)) if n else 0.0, int(n)) for k, (a, n) in sse.items()}


def errors(
    units: Sequence[Unit], model: Model, *, bases: Sequence | None = None, predictions: Predictions | None = None
) -> Errors:
    """RMSEs of ``model`` on ``units``; ``bases`` optionally holds each unit's precomputed base wrench, or
    ``predictions`` caches them across calls."""
    df, dt = [], []
    for k, u in enumerate(units):
        if predictions is not None:
            f, t = predictions(u, model)
        else:
            f, t = predict(u, model, base=None if bases is None else bases[k])
        df.append(u.force_N[:, 2] - f[:, 2])
        dt.append(u.torque_Nm - t)
    df_a, dt_a = np.concatenate(df), np.concatenate(dt)
    return Errors(
        rmse_fz_N=float(np.sqrt(np.mean(df_a**2))),
        rmse_torque_Nm=float(np.sqrt(np.mean(np.sum(dt_a**2, axis=1)))),
        rmse_tz_Nm=float(np.sqrt(np.mean(dt_a[:, 2] ** 2))),
        n_samples=int(df_a.size),
    )
