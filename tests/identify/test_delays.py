"""A delay on a library effect (issue 35: "a lag on any effect"; proxplan.identify.delayed,
proxplan.physics.LAG_PARAM): exact at the fits' sparse stratified rows, and found with its delay by the
whole identify pipeline."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from proxplan.identify.data import IdentifyOptions, Model, errors, predict
from proxplan.identify.delayed import delayed_units, with_rows
from proxplan.identify.loading import load_units
from proxplan.identify.manifest import load_manifest
from proxplan.identify.strata import stratified_sample
from proxplan.physics import Effect, EffectInputs, ModelOptions, effect_wrench

from .test_discovery import _manifest, _run

LATE_S = 0.3
"""Delay of the hidden effect, s: between two points of the profile's grid (0.253 and 0.38 s)."""
LATE_AMPLITUDE = 3.0
"""Strength of the hidden effect (near_field's ``amplitude``), -: strong enough that the vehicle parameters could
absorb part of it (the discovery benchmark draws effects of 1.5-4 times the clean error)."""
LATE_NEAR_FIELD = Effect("near_field", {"amplitude": LATE_AMPLITUDE, "decay_L": 3.0, "lag_s": LATE_S})


def late_near_field(inputs: EffectInputs) -> tuple[np.ndarray, np.ndarray]:
    """The library's near_field felt LATE_S late: a wake that takes that long to reach the vehicle below."""
    return effect_wrench(LATE_NEAR_FIELD, inputs)


def test_a_delayed_effect_at_stratified_rows_is_the_full_rate_delay(tmp_path: Path) -> None:
    """The fits' stratified rows are sparse and out of order in time: each row's delayed state, taken on the
    full-rate flight it comes from, predicts what the delay along the full-rate log predicts at that row."""
    manifest = load_manifest(_manifest(tmp_path, None, n_flights=3, duration_s=8.0))
    data = load_units(manifest, options=IdentifyOptions())
    model = Model(vehicles=data.types, thrust_scale={}, options=ModelOptions(), effects=(LATE_NEAR_FIELD,))
    units = [u for u in data.units if u.split == "train"]
    full = with_rows([u for u in units if len(u)])
    rows = stratified_sample(full, 600, model.vehicles)
    assert sum(len(u) for u in rows) < 0.5 * sum(len(u) for u in full)  # sparse indeed
    along_log = np.concatenate([predict(u, model)[0][:, 2] for u in full])
    for u, d in zip(rows, delayed_units(rows, full, [LATE_S])):
        at_rows = predict(u, model, delayed=d)[0][:, 2]
        np.testing.assert_allclose(at_rows, along_log[u.row], rtol=1e-9, atol=1e-12)
        # and along the sparse rows' own clock it would be wrong (what the delayed state is for)
        if len(u) > 50:
            assert np.abs(predict(u, model)[0][:, 2] - at_rows).max() > 1e-4


@pytest.fixture(scope="module")
def clean(discovery_clean):
    return discovery_clean


def test_a_late_library_effect_is_found_with_its_delay(tmp_path: Path, clean) -> None:
    """near_field felt 0.3 s late, in none of the profile's grid points: selection keeps near_field with its
    delay refined to within 10 ms, and the lower vehicle's test F_z error comes within 1.3x of the same logs
    without it (tried only at once, its error stayed several times the clean one: docs/identify.md).

    Its strength comes out within 5 % of the hidden one: the delayed effect is judged on F_z and yaw only but
    fitted, with the survivors, on every channel it acts on (proxplan.identify.selection.joint_model). Fitted
    on the judged channels, its roll and pitch torque was left to the vehicle parameters' tangents, which took
    part of it near the source: 2.71 (10 % low, the source's c_ax moved 4 %), and on the discovery benchmark's
    draw 0 (a large and a small vehicle) 1.69 of 2.82 with the F_z error 2.0x the clean one."""
    result, test_b = _run(tmp_path, late_near_field)
    (kept,) = [e for e in result.final_model.effects if e.name == "near_field"]
    assert abs(kept.lag_s - LATE_S) <= 0.01, kept
    assert abs(kept.params["amplitude"] / LATE_AMPLITUDE - 1.0) <= 0.05, kept
    assert set(result.selected) <= {"thrust_bias", "near_field"}, result.selected
    clean_rmse = errors(clean[1], clean[0].final_model).rmse_fz_N
    assert errors(test_b, result.base_model).rmse_fz_N > 2.0 * clean_rmse  # visible
    assert errors(test_b, result.final_model).rmse_fz_N <= 1.3 * clean_rmse
