"""The selections around the calibrated and the prior model run side by side on two Dask workers
(proxplan.identify.two_starts) give what they give one after the other in this process, bit for bit: the
kept effects and terms, every coefficient, the held-out totals and the test errors."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from proxplan.identify import run_identify

from .test_discovery import OPTIONS, _manifest, swept_wake


@pytest.mark.slow
def test_two_workers_give_the_serial_result(tmp_path: Path) -> None:
    manifest = _manifest(tmp_path, swept_wake, n_flights=4, duration_s=10.0)
    serial = run_identify(manifest, options=replace(OPTIONS, workers=0), thrust_summary=False)
    fanned = run_identify(manifest, options=replace(OPTIONS, workers=2), thrust_summary=False)
    assert "selection around the prior model (own wall)" in fanned.timings  # both starts ran
    assert fanned.selected == serial.selected
    assert [e.params for e in fanned.final_model.effects] == [e.params for e in serial.final_model.effects]
    assert fanned.final_model.thrust_scale == serial.final_model.thrust_scale
    assert fanned.final_model.vehicles == serial.final_model.vehicles
    assert fanned.selection == serial.selection
    assert fanned.after.rmse_fz_N == serial.after.rmse_fz_N
