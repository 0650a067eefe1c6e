"""The delivered fit's channel weights (:mod:`proxplan.identify.channel_variance`): noise plus what the kept
set leaves unexplained, per vehicle type and channel."""

import sys
from pathlib import Path

import numpy as np
import pytest

from proxplan.identify.channel_variance import structural_row_weight


def _rows(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    residual = rng.normal(size=(2 * n, 4))
    types = np.array(["small"] * n + ["large"] * n, dtype=object)
    return residual, types, np.ones(2 * n)


def test_a_channel_holding_unexplained_structure_is_weighed_by_its_error_and_no_other_is():
    rng = np.random.default_rng(0)
    n = 4000
    residual, types, train = _rows(rng, n)
    residual[n:, 1] += 3.0 * np.sin(np.linspace(0.0, 40.0, n))  # the large type's roll: structure of variance 4.5
    factor, mse = structural_row_weight(residual, types, train)
    assert abs(mse["large"][1] - 5.5) < 0.5  # 1 (noise) + 4.5 (structure)
    assert np.allclose(factor[n:, 1], 1.0 / np.sqrt(mse["large"][1]))
    # every other channel, and the small type's roll, are explained to their noise: weight 1 within the
    # sampling spread of a mean square of 4000 unit normals (SE 0.022; 0.1 is 4.5 SE), never above 1
    others = np.ones((2 * n, 4), dtype=bool)
    others[n:, 1] = False
    assert np.all(factor[others] <= 1.0) and np.all(factor[others] > 1.0 / np.sqrt(1.1))


def test_rows_outside_the_fit_do_not_set_the_weights_and_a_channel_without_signal_stays_neutral():
    rng = np.random.default_rng(1)
    n = 2000
    residual, types, train = _rows(rng, n)
    residual[:n, 0] += 10.0  # large errors on rows the fit does not use
    train[:n] = 0.0
    train[: n // 2] = 1.0  # ... except half of them
    residual[:, 3] = np.inf  # a channel with no measured signal (noise unit inf upstream)
    factor, mse = structural_row_weight(residual, types, train)
    assert 50.0 < mse["small"][0] < 150.0  # the used half: 1 + 100
    assert np.isnan(mse["small"][3]) and np.all(factor[:, 3] == 1.0)


@pytest.mark.slow
def test_an_unexplained_torque_no_longer_bends_the_thrust_scale_of_the_vehicle_above() -> None:
    """Discovery draw 20006 (docs/identify.md, stops 61 and 62): a kernel torque on the large quad from the
    small one above, on 2 of 4 train flights, that nothing finds. Weighted by the noise units alone, the
    delivered fit's tangents bent to it and the small quad, which nothing affects, ended at 6.4x its clean
    twin's test F_z error (0.316 -> 2.02 g); weighted by each channel's held-out error it is within the
    benchmark's 1.3x (1.01x at stop 62)."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
    from bench_discovery import run_draw

    draw = run_draw((20006, "kernel", ""))
    assert draw["affected"] == ["v1"] and draw["types"]["v0"] == "small-quad"  # the case traced
    assert draw["ratios"]["v0"] <= 1.3, draw["ratios"]
    assert not draw["harmed"]
