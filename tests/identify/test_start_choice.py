"""The two starts of selection (around the calibrated and the prior model) are compared on held-out F_z
(identify.selection.other_start_better): the question they answer is what the calibration, a fit on F_z, absorbed."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.identify.noise import CHANNELS
from proxplan.identify.selection import SCORE_RESOLUTION, Selection, other_start_better


def _selection(start: str, mse: np.ndarray) -> Selection:
    """A selection with only its held-out MSE ((groups, channels), noise units) filled in."""
    return Selection(model=None, effects=None, discovery=None, start=start, heldout_mse=mse, note="",  # type: ignore[arg-type]
                     cluster=np.arange(len(mse)), rows=[], heldout_fz_N=np.zeros(0))  # fmt: skip


def test_channels_are_in_the_order_the_score_reads() -> None:
    assert CHANNELS[0] == "force_z_N"


def test_f_z_decides_when_a_torque_term_favours_the_other_start() -> None:
    """The near_field replicate's figures (stop 66): the prior start predicts F_z better (1.036 against
    1.069), the calibrated start torque_y (0.117 against 0.189); summed over channels the calibrated one won."""
    groups = 6
    prior = _selection("prior", np.tile([1.036, 0.126, 0.189, 1.337], (groups, 1)))
    calibrated = _selection("calibrated", np.tile([1.069, 0.142, 0.117, 1.337], (groups, 1)))
    assert calibrated.heldout_total < prior.heldout_total  # all channels: the calibrated start
    assert prior.heldout_fz_total == pytest.approx(np.log(1.036))
    assert other_start_better(calibrated, prior)  # F_z: the prior start
    assert not other_start_better(prior, calibrated)


def test_within_the_resolution_the_calibrated_start_stays() -> None:
    mse = np.tile([1.0, 1.0, 1.0, 1.0], (4, 1))
    calibrated = _selection("calibrated", mse)
    nudged = mse.copy()
    nudged[:, 0] *= np.exp(-0.5 * SCORE_RESOLUTION)  # better by half the resolution
    assert not other_start_better(calibrated, _selection("prior", nudged))
    nudged[:, 0] = mse[:, 0] * np.exp(-2.0 * SCORE_RESOLUTION)
    assert other_start_better(calibrated, _selection("prior", nudged))


def test_groups_without_f_z_are_left_out_of_the_score() -> None:
    mse = np.array([[1.0, 1.0, 1.0, 1.0], [np.nan, 2.0, 2.0, 2.0], [np.e, 1.0, 1.0, 1.0]])
    assert _selection("prior", mse).heldout_fz_total == pytest.approx(0.5)
