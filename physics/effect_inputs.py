r"""The situation of one target vehicle that every effect is evaluated on (:class:`EffectInputs`, its
:class:`SourceSample`\ s) and the base downwash model over its sources (S0-3..S0-8 with the stack
shielding of :mod:`proxplan.physics.stack`), computed once per situation (:class:`BaseCache`). Split from
:mod:`proxplan.physics.effects`, which applies the effect library on top of it.

Frames as in :mod:`proxplan.physics.effects`: world frame, z up; ``offsets_m`` = p_target - p_source, m.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from proxplan.physics.disturbance import (
    DEFAULT_OPTIONS,
    ModelOptions,
    disturbance_wrench,
)
from proxplan.physics.room import Plane
from proxplan.physics.stack import shielding_factors
from proxplan.physics.vehicles import Vehicle


@dataclass(frozen=True)
class SourceSample:
    """One other vehicle acting as a downwash source, per sample."""

    vehicle: Vehicle
    offsets_m: np.ndarray  # (N, 3) p_target - p_source, world frame, m
    velocity_mps: np.ndarray | None = None  # (N, 3) the source's own velocity, world, m/s (None: unknown)


@dataclass(frozen=True)
class EffectInputs:
    """Situation of ONE target vehicle over N samples."""

    target: Vehicle
    height_above_ground_m: np.ndarray  # (N,) rotor plane above the ground, m
    velocity_mps: np.ndarray  # (N, 3) the target's own velocity, world frame, m/s
    sources: tuple[SourceSample, ...] = ()
    options: ModelOptions = DEFAULT_OPTIONS
    time_s: np.ndarray | None = None  # (N,) sample times, s (None: independent steady states)
    thrust_z_N: np.ndarray | None = None  # (N,) own collective thrust along world z, N (None: unknown)
    position_m: np.ndarray | None = None  # (N, 3) the target's position, world frame, m (None: unknown)
    planes: tuple[Plane, ...] = ()  # planes of the room (proxplan.physics.room), for place features

    @property
    def n_samples(self) -> int:
        return int(np.shape(self.height_above_ground_m)[0])


def zeros_wrench(n: int) -> tuple[np.ndarray, np.ndarray]:
    """A zero force (n, 3) N and torque (n, 3) N m."""
    return np.zeros((n, 3)), np.zeros((n, 3))


def base_source_wrench(source: SourceSample, target: Vehicle, options: ModelOptions) -> tuple[np.ndarray, np.ndarray]:
    """The base wrench of one ``source`` on ``target`` without shielding (S0-3..S0-8): force (N, 3) N, torque (N, 3) N m."""
    batch = disturbance_wrench(source.vehicle, target, source.offsets_m, options)
    return batch.force_N, batch.torque_Nm


class BaseCache:
    """Base wrench of each source of one :class:`EffectInputs`, computed once when first needed:
    (S0-3..S0-8) per source times the share of its jet that reaches the target past the other
    sources' rotors (:func:`proxplan.physics.stack.shielding_factors`; 1 with a single source above)."""

    def __init__(self, inputs: EffectInputs):
        self.inputs = inputs
        self._per_source: list | None = None
        self._factors: list[np.ndarray] | None = None

    def factors(self) -> list[np.ndarray]:
        """Per source, the shielding factor (N,), -."""
        if self._factors is None:
            srcs = self.inputs.sources
            self._factors = shielding_factors(
                [s.offsets_m for s in srcs], [s.vehicle for s in srcs], self.inputs.options.stack_shielding,
                self.inputs.options.discretisation,
            )  # fmt: skip
        return self._factors

    def per_source(self) -> list[tuple[np.ndarray, np.ndarray]]:
        if self._per_source is None:
            self._per_source = [
                (f * s[:, None], t * s[:, None])
                for (f, t), s in zip(
                    (base_source_wrench(src, self.inputs.target, self.inputs.options) for src in self.inputs.sources),
                    self.factors(),
                )
            ]
        return self._per_source


def sum_base(inputs: EffectInputs, cache: BaseCache) -> tuple[np.ndarray, np.ndarray]:
    """The base wrench of ``cache`` summed over the sources: force (N, 3) N, torque (N, 3) N m."""
    force, torque = zeros_wrench(inputs.n_samples)
    for f, t in cache.per_source():
        force += f
        torque += t
    return force, torque


def base_cache(inputs: EffectInputs) -> BaseCache:
    """A :class:`BaseCache` of ``inputs`` (pass it to :func:`proxplan.physics.effects.effect_wrench` to evaluate many effects, or
    one effect many times, on the same samples with one base-model evaluation)."""
    return BaseCache(inputs)


def base_wrench_per_source(inputs: EffectInputs) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per source, the base wrench (force (N, 3) N, torque (N, 3) N m) as :func:`base_wrench` sums it
    (S0-3..S0-8 with the stack shielding of :mod:`proxplan.physics.stack`)."""
    return BaseCache(inputs).per_source()


def base_wrench(inputs: EffectInputs) -> tuple[np.ndarray, np.ndarray]:
    """Base model (S0-3..S0-8) summed over all sources: force (N, 3), N; torque (N, 3), N m."""
    return sum_base(inputs, BaseCache(inputs))
