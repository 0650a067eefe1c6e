"""The seed's horizontal sweeps (S0 IV-F): small quad hovering above the large quad, target moving
along y from -1 to 1 m at dz in {0.5, 1.0, 1.5, 2.0, 2.5} m. Checks the observations of S0 IV-H."""

import numpy as np
import pytest

from proxplan.physics import ModelOptions, authority_usage, disturbance_wrench, oncoming_speed_per_rotor_mps
from proxplan.physics.builtin_vehicles import LARGE_QUAD, SMALL_QUAD

DZ_M = (0.5, 1.0, 1.5, 2.0, 2.5)
Y_M = np.linspace(-1.0, 1.0, 401)  # symmetric grid containing y = 0 at index 200
CENTRE = 200


def sweep(dz_m: float, form: str = "inverse-z"):
    offsets = np.column_stack([np.zeros_like(Y_M), Y_M, np.full_like(Y_M, -dz_m)])
    return disturbance_wrench(SMALL_QUAD, LARGE_QUAD, offsets, ModelOptions(field_form=form))


def test_thrust_change_dominates_drag_beyond_one_metre():
    for dz in DZ_M:
        w = sweep(dz)
        drag, thrust = np.abs(w.drag_force_N[:, 2]).max(), np.abs(w.thrust_force_N[:, 2]).max()
        if dz > 1.0:
            assert thrust > 3.0 * drag, (dz, thrust, drag)


def test_force_peaks_on_axis_and_torques_have_the_right_symmetry():
    for dz in DZ_M:
        w = sweep(dz)
        fz, tx = w.force_N[:, 2], w.torque_Nm[:, 0]
        assert np.argmax(np.abs(fz)) == CENTRE
        assert fz[CENTRE] < 0.0  # pushed down
        np.testing.assert_allclose(fz, fz[::-1], rtol=1e-9, atol=1e-12)  # even in y
        np.testing.assert_allclose(tx, -tx[::-1], rtol=1e-9, atol=1e-12)  # odd in y
        assert abs(tx[CENTRE]) < 1e-12
        peak = np.argmax(np.abs(tx))
        assert 0.02 < abs(Y_M[peak]) < 0.6  # roll torque peaks off axis
        scale = np.abs(tx).max()
        assert np.abs(w.torque_Nm[:, 1]).max() < 1e-9 * scale  # no pitch along a y sweep
        assert np.abs(w.torque_Nm[:, 2]).max() == 0.0  # no yaw (S0 II-B)
        assert np.abs(w.force_N[:, :2]).max() == 0.0  # axial flow only


def test_spread_grows_with_dz_and_peak_rises_then_falls():
    peaks, widths = [], []
    for dz in DZ_M:
        fz = np.abs(sweep(dz).force_N[:, 2])
        peaks.append(fz.max())
        above_half = Y_M[fz >= 0.5 * fz.max()]
        widths.append(above_half.max() - above_half.min())
    assert peaks[0] < peaks[2]  # narrow jet at 0.5 m misses most of the disks
    assert all(b > a for a, b in zip(widths, widths[1:])), widths
    top = int(np.argmax(peaks))
    assert 0 < top < len(DZ_M) - 1, peaks  # interior maximum: rises, then falls
    assert all(b > a for a, b in zip(peaks[: top + 1], peaks[1 : top + 1]))
    assert all(b < a for a, b in zip(peaks[top:], peaks[top + 1 :]))


def test_force_magnitude_matches_paper_and_printed_form_overshoots():
    """S0 IV-H: forces on the large quad were about 10 % of its weight. The 1/z form of (S0-1)
    lands in 5-15 % over dz in [1.0, 2.5] m; the printed 1/sqrt(z) form overshoots (DESIGN.md s. 2)."""
    weight_N = LARGE_QUAD.weight_N
    for dz in (1.0, 1.5, 2.0, 2.5):
        fraction = -sweep(dz).force_N[CENTRE, 2] / weight_N
        assert 0.05 <= fraction <= 0.15, (dz, fraction)
    printed = [-sweep(dz, "printed").force_N[CENTRE, 2] / weight_N for dz in (1.0, 1.5, 2.0, 2.5)]
    assert max(printed) > 0.15, printed
    # and the printed form is still rising at 2.5 m, unlike the paper's observation 4
    assert printed[-1] > printed[-2]


def test_validity_flag_and_authority_usage():
    L = SMALL_QUAD.size_m
    offsets = np.array([[0, 0, -2.9 * L], [0, 0, -3.0 * L], [0, 0, -3.01 * L], [0, 0, -10 * L]])
    w = disturbance_wrench(SMALL_QUAD, LARGE_QUAD, offsets)
    assert w.valid.tolist() == [False, False, True, True]
    dz = 1.5
    r = np.array([5.0, 1.0, 0.5, 0.3, 0.2, 0.1, 0.0])
    ww = disturbance_wrench(SMALL_QUAD, LARGE_QUAD, np.column_stack([r, 0 * r, np.full_like(r, -dz)]))
    usage = authority_usage(LARGE_QUAD, ww.force_N, ww.torque_Nm)
    assert usage[0] < 1e-9  # far away: untouched
    # grows towards the axis; the maximum sits slightly off axis, where the roll torque adds to
    # the thrust loss (the torque vanishes at r = 0), so r = 0 itself stays close to that maximum
    assert np.all(np.diff(usage[:-1]) > 0.0), usage
    assert usage[-1] > 0.5 * usage.max() and usage[-1] > 0.01


def test_target_above_source_feels_nothing():
    w = disturbance_wrench(SMALL_QUAD, LARGE_QUAD, np.array([[0.0, 0.0, 0.5], [0.0, 0.1, 0.0]]))
    assert np.all(w.force_N == 0.0) and np.all(w.torque_Nm == 0.0)


def test_disk_average_differs_from_hub_value_in_a_narrow_jet():
    """At small dz the jet is narrower than a disk: averaging over the disk must not equal the hub
    value (S0 IV-H observation 3)."""
    rotor = LARGE_QUAD.rotor_positions_m[3]
    offset = np.array([[-rotor[0], -rotor[1], -0.5]])  # rotor 4 right under the source
    v_on = oncoming_speed_per_rotor_mps(SMALL_QUAD, LARGE_QUAD, offset)[0, 3]
    from proxplan.physics import centreline_speed_mps

    hub_speed = float(centreline_speed_mps(SMALL_QUAD, np.array(0.5)))
    assert v_on < 0.8 * hub_speed


def test_batch_equals_single_offsets_and_input_validation():
    rng = np.random.default_rng(1)
    offsets = rng.uniform([-1, -1, -3], [1, 1, -0.2], size=(20, 3))
    batch = disturbance_wrench(LARGE_QUAD, SMALL_QUAD, offsets)
    for i in (0, 7, 19):
        single = disturbance_wrench(LARGE_QUAD, SMALL_QUAD, offsets[i])
        np.testing.assert_allclose(single.force_N[0], batch.force_N[i])
        np.testing.assert_allclose(single.torque_Nm[0], batch.torque_Nm[i])
    with pytest.raises(ValueError):
        disturbance_wrench(LARGE_QUAD, SMALL_QUAD, np.array([[0.0, np.nan, -1.0]]))
    with pytest.raises(ValueError):
        disturbance_wrench(LARGE_QUAD, SMALL_QUAD, np.zeros((4, 2)))


def test_finer_discretisation_converges():
    from proxplan.physics.geometry import Discretisation

    offsets = np.array([[0.0, y, -1.5] for y in (0.0, 0.1, 0.25)])
    coarse = disturbance_wrench(SMALL_QUAD, LARGE_QUAD, offsets)
    fine = disturbance_wrench(
        SMALL_QUAD, LARGE_QUAD, offsets,
        ModelOptions(discretisation=Discretisation(disk_rings=16, disk_spokes=32, hub_cells=9, arm_segments=16)),
    )  # fmt: skip
    np.testing.assert_allclose(coarse.force_N[:, 2], fine.force_N[:, 2], rtol=0.03)
