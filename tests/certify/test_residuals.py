"""The residual process defaults match what the Neural-Swarm hover logs show."""

from __future__ import annotations

import pytest

from proxplan.certify import NoiseSpec
from proxplan.certify.residuals import residual_statistics
from tests.conftest import SHARED

ROOT = SHARED / "data" / "neural-swarm"


@pytest.mark.skipif(not (ROOT / "takeoff_s").is_dir(), reason="Neural-Swarm logs not present")
def test_default_residual_process_lies_within_the_measured_statistics():
    stats = residual_statistics(ROOT)
    assert set(stats) == {"crazyflie-2.1", "crazyflie-parrot"}
    noise = NoiseSpec()
    for s in stats.values():
        assert s.samples > 300
        assert 0.5 < noise.residual_std_z_weight / s.std_z_weight < 2.0
        assert 0.5 < noise.residual_std_xy_weight / s.std_xy_weight < 2.0
        assert 0.3 < noise.residual_tau_s / s.tau_s < 3.0
        assert s.std_z_weight > s.std_xy_weight  # the thrust axis carries most of the residual
