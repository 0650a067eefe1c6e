"""identify on generated flights, for the tests that hide a wrench in synthetic logs and judge what identify keeps."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np

from proxplan.identify import IdentifyResult, run_identify, synthetic_logs, write_synthetic_manifest
from proxplan.identify.data import IdentifyOptions, errors
from proxplan.physics import BUILTIN_VEHICLES


def identify_flights(
    tmp: Path,
    types: Mapping[str, str],
    motions: Callable[[np.ndarray, int], dict[str, np.ndarray]],
    hidden,
    *,
    options: IdentifyOptions,
    n_flights: int,
    n_test: int,
    duration_s: float = 16.0,
) -> IdentifyResult:
    """``n_flights`` generated flights of the vehicles ``types`` (name -> built-in type) sampled at 100 Hz for
    ``duration_s`` (s), flight k flying ``motions(t_s, k)`` (name -> (N, 3) positions, m, world) with the hidden
    wrench ``hidden`` (None: none; :func:`proxplan.identify.synthetic_logs`), accelerometer noise 0.02 m/s^2 and
    motor noise 0.004 N, seeded by k; the last ``n_test`` flights are test flights, the rest train. Returns
    identify's result on them."""
    t = np.arange(0.0, duration_s, 0.01)
    vehicles = {v: BUILTIN_VEHICLES[typ] for v, typ in types.items()}
    flights = [
        (f"f{k}", "test" if k >= n_flights - n_test else "train", synthetic_logs(
            vehicles, motions(t, k), t, hidden_wrench=hidden, accel_noise_mps2=0.02, motor_noise_N=0.004, seed=k,
        ))
        for k in range(n_flights)
    ]  # fmt: skip
    return run_identify(write_synthetic_manifest(tmp, flights, dict(types)), options=options, thrust_summary=False)


def kept_terms(result: IdentifyResult) -> dict[str, float]:
    """Every discovered term identify kept: its key -> its coefficient."""
    return {k: v for e in result.discovered if e["selected"] for k, v in e["params"].items()}


def torque_rmse_on_test_Nm(result: IdentifyResult, vehicle: str) -> float:
    """RMSE of the torque's norm (N m) on ``vehicle``'s test flights under the delivered model."""
    units = [u for u in result.units if u.split == "test" and u.name == vehicle]
    return errors(units, result.final_model).rmse_torque_Nm
