"""Stacks in identification: logs of three vehicles whose truth is NOT the sum of pair wrenches (the
middle vehicle shields the bottom one from the top one's jet, proxplan.physics.stack with eta = 1).
The per-pair sum ("before", S0's superposition) misses the stacks; identify chooses eta on the
train flights with the rest (MAP, its prior) and brings the bottom vehicle's stacked samples within 1.3x of
the error the truth itself leaves (measurement noise)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from proxplan.identify import run_identify, synthetic_logs, write_synthetic_manifest
from proxplan.identify.data import IdentifyOptions, Model
from proxplan.identify.strata import stacked_samples
from proxplan.physics import BUILTIN_VEHICLES, ModelOptions

VEHICLE_TYPE = "small-quad"
VEH = BUILTIN_VEHICLES[VEHICLE_TYPE]
TRUE_ETA = 1.0


def _trajectories(t: np.ndarray, phase: float) -> dict[str, np.ndarray]:
    """Three vehicles on one vertical line now and then: 'top' and 'mid' sway in x, 'low' in y, so the
    bottom one passes under one, two or no vehicles."""

    def sway(amp: float, period: float, ph: float) -> np.ndarray:
        return amp * np.sin(2 * np.pi * t / period + ph)

    return {
        "top": np.column_stack([sway(0.25, 5.0, phase), sway(0.05, 7.0, phase), 1.9 + 0 * t]),
        "mid": np.column_stack([sway(0.2, 4.0, 2 * phase), 0 * t, 1.45 + sway(0.05, 3.0, phase)]),
        "low": np.column_stack([sway(0.06, 6.0, phase), sway(0.25, 4.5, 3 * phase), 0.95 + sway(0.1, 5.5, phase)]),
    }


def _flights(n: int = 5):
    t = np.arange(0.0, 20.0, 0.01)
    vehicles = {"top": VEH, "mid": VEH, "low": VEH}
    return [
        (f"stack_{k:02d}", "test" if k == n - 1 else "train",
         synthetic_logs(vehicles, _trajectories(t, 0.9 * k), t, accel_noise_mps2=0.02, motor_noise_N=0.002, seed=k))
        for k in range(n)
    ]  # fmt: skip


def _stack_rmse(result, model: Model) -> float:
    from proxplan.identify.data import predict

    res = []
    for u in result.units:
        if u.split == "test" and u.name == "low":
            m = stacked_samples(u, model)
            res.append((u.force_N[:, 2] - predict(u, model)[0][:, 2])[m])
    return float(np.sqrt(np.mean(np.concatenate(res) ** 2)))


@pytest.fixture(scope="module")
def result(tmp_path_factory: pytest.TempPathFactory):
    manifest = write_synthetic_manifest(tmp_path_factory.mktemp("stack"), _flights(), VEHICLE_TYPE)
    opts = IdentifyOptions(max_fit_samples=3000, max_eval_samples=2500, discover=False)
    return run_identify(manifest, options=opts, thrust_summary=False)


def test_additive_model_misses_the_stack_and_the_chosen_eta_recovers_it(result) -> None:
    truth = Model(vehicles=dict(result.base_model.vehicles), options=ModelOptions(stack_shielding=TRUE_ETA))
    additive = replace(result.final_model, options=replace(result.final_model.options, stack_shielding=0.0))
    clean, before, after = (_stack_rmse(result, m) for m in (truth, additive, result.final_model))
    assert result.stack_shielding is not None and result.stack_shielding["std"] < 0.5  # informed by the stacks
    assert before > 2.0 * clean, (before, clean)  # the per-pair sum is wrong where two are above
    assert after <= 1.3 * clean, (after, clean, result.stack_shielding)
