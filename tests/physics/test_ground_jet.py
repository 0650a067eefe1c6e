"""ground_jet: a source's jet meeting the floor pushes a low target less (proxplan.physics.effects)."""

from __future__ import annotations

import numpy as np

from proxplan.physics import BUILTIN_VEHICLES, Effect, EffectInputs, SourceSample, base_wrench, effect_wrench

VEH = BUILTIN_VEHICLES["small-quad"]


def _inputs(h: np.ndarray, dz_m: float) -> EffectInputs:
    n = len(h)
    return EffectInputs(VEH, h, np.zeros((n, 3)), (SourceSample(VEH, np.tile([0.0, 0.0, -dz_m], (n, 1))),))


def test_ground_jet_weakens_the_push_near_the_floor_only() -> None:
    h = np.array([0.02, 0.1, 0.3, 1.0, 5.0])
    inputs = _inputs(h, 0.5)
    eff = Effect("ground_jet", {"amplitude_1": 0.6, "decay_L": 2.0})
    f, t = effect_wrench(eff, inputs)
    base_f, _ = base_wrench(inputs)
    total = base_f[:, 2] + f[:, 2]
    assert np.all(base_f[:, 2] < 0.0)
    assert np.all(total < 0.0) and np.all(total > base_f[:, 2])  # less push, never reversed
    assert np.all(np.diff(f[:, 2]) < 0.0)  # the correction fades with height
    assert abs(f[-1, 2]) < 1e-6 * abs(base_f[-1, 2])
    ratio = (1 - 0.6 * np.exp(-h[1] / (2.0 * VEH.size_m))) ** 2  # v^2 scaling of the impinging jet
    np.testing.assert_allclose(total[1], ratio * base_f[1, 2], rtol=1e-9)


def test_ground_jet_is_zero_without_a_source_above() -> None:
    inputs = _inputs(np.array([0.05, 0.2]), -0.5)  # source BELOW the target
    f, t = effect_wrench(Effect("ground_jet", {}), inputs)
    assert np.all(f == 0.0) and np.all(t == 0.0)
