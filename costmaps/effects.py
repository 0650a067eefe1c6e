"""The wrench of one source on one target with a calibrated model's effects between vehicles: the
one function cost maps, planner checks and verifier evaluate (one implementation, DESIGN.md s. 6).

Frames: world z up; ``offsets_m`` (N, 3) = p_target - p_source, m; force (N, 3) N and torque (N, 3)
N m on the target about its centre of mass, world frame. Without effects this is
:func:`proxplan.physics.disturbance.disturbance_wrench` (S0-3..S0-8); with effects it is
:func:`proxplan.physics.effects.total_wrench` for this one source, keeping only the effects that act
between vehicles (every effect not in :data:`proxplan.physics.effects.TARGET_ONLY_EFFECTS`, each a sum over
sources like the base model). The target is taken far above the ground and at rest: effects of the
target alone (ground effect, own velocity, thrust bias) are its own thrust error, not the plan's.
:func:`sources_wrench` evaluates several sources at once (the verifier, where two are above a target).

Cost maps assume an axisymmetric jet (one quadrant, mirrored); :data:`AXIS_BREAKING_EFFECTS` (a wake
carried sideways by wind) break that symmetry and are left out of the maps and the planner's tables
(:func:`map_effects`), while the verifier and the simulator apply them.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np

from proxplan.physics import (
    DEFAULT_OPTIONS,
    Effect,
    EffectInputs,
    ModelOptions,
    SourceSample,
    Vehicle,
    between_vehicle_effects,
    disturbance_wrench,
    total_wrench,
)

AXIS_BREAKING_EFFECTS = ("wake_advection",)
"""Effects that make the wrench depend on the azimuth of the offset (not applied by cost maps)."""

FAR_ABOVE_GROUND_M = 1.0e6  # height above ground of the target in pair wrenches (no ground effect), m

EffectsKey = tuple[tuple[str, tuple[tuple[str, float], ...]], ...]
"""Hashable canonical form of effects (name, sorted full parameters), for caches and hashes."""


def effects_key(effects: Iterable[Effect]) -> EffectsKey:
    """The canonical hashable form of the between-vehicle ``effects`` (order kept)."""
    return tuple((e.name, tuple(sorted(e.full_params().items()))) for e in between_vehicle_effects(effects))


def effects_of_key(key: EffectsKey) -> tuple[Effect, ...]:
    """The effects back from :func:`effects_key`."""
    return tuple(Effect(name, dict(params)) for name, params in key)


def map_effects(effects: Iterable[Effect]) -> tuple[Effect, ...]:
    """The effects cost maps apply: between vehicles and keeping the jet axisymmetric."""
    return tuple(e for e in between_vehicle_effects(effects) if e.name not in AXIS_BREAKING_EFFECTS)


def unmapped_effect_names(effects: Iterable[Effect]) -> list[str]:
    """Names of between-vehicle effects the cost maps (and so the planner) cannot apply."""
    return [e.name for e in between_vehicle_effects(effects) if e.name in AXIS_BREAKING_EFFECTS]


def pair_wrench(
    source: Vehicle,
    target: Vehicle,
    offsets_m: np.ndarray,
    options: ModelOptions = DEFAULT_OPTIONS,
    effects: Sequence[Effect] = (),
) -> tuple[np.ndarray, np.ndarray]:
    """Force (N, 3), N, and torque (N, 3), N m, on ``target`` from ``source`` at ``offsets_m``
    (N, 3) = p_target - p_source, m: base model plus the between-vehicle ``effects``."""
    offsets = np.asarray(offsets_m, dtype=float).reshape(-1, 3)
    between = between_vehicle_effects(effects)
    if not between:
        batch = disturbance_wrench(source, target, offsets, options)
        return batch.force_N, batch.torque_Nm
    n = offsets.shape[0]
    inputs = EffectInputs(
        target=target,
        height_above_ground_m=np.full(n, FAR_ABOVE_GROUND_M),
        velocity_mps=np.zeros((n, 3)),
        sources=(SourceSample(source, offsets),),
        options=options,
    )
    return total_wrench(inputs, between)


def sources_wrench(
    target: Vehicle,
    sources: Sequence[tuple[Vehicle, np.ndarray]],
    options: ModelOptions = DEFAULT_OPTIONS,
    effects: Sequence[Effect] = (),
) -> tuple[np.ndarray, np.ndarray]:
    """Force (N, 3), N, and torque (N, 3), N m, on ``target`` from every ``(source, offsets_m)``
    at once (offsets (N, 3) = p_target - p_source, m): :func:`proxplan.physics.effects.total_wrench` with
    the between-vehicle ``effects``. Equal to the sum of :func:`pair_wrench` over the sources for
    effects that add over sources (all of today's); an effect that does not (several sources
    interacting) is only right here."""
    n = int(np.shape(sources[0][1])[0]) if sources else 0
    inputs = EffectInputs(
        target=target,
        height_above_ground_m=np.full(n, FAR_ABOVE_GROUND_M),
        velocity_mps=np.zeros((n, 3)),
        sources=tuple(SourceSample(v, np.asarray(o, dtype=float).reshape(-1, 3)) for v, o in sources),
        options=options,
    )
    return total_wrench(inputs, between_vehicle_effects(effects))
