"""The search that refines a kept term's scales (proxplan.identify.refine): a scan, then golden steps, in log scale;
a kept kernel on the grid, a kept time copy off it, and kept siblings merged into one term."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.identify.refine import DECAY_RATIO, LAG_RATIO, LOWPASS_RATIO, WIDTH_RATIO, _golden_min, _line
from proxplan.physics import LAGS_S, LOWPASS_TAUS_S, feature_matrix, lagged, lowpass, parse_time_name


def test_the_line_search_finds_a_minimum_inside_the_bracket_to_a_fraction_of_a_percent() -> None:
    """A held-out error with its minimum at 0.77 L, searched from the grid width 1 L within the grid's ratio 2.5:
    found within 1 %; a minimum beyond the bracket ends on its edge (never outside the grid's step)."""
    calls: list[float] = []

    def f(w: float) -> float:
        calls.append(w)
        return (np.log(w / 0.77)) ** 2 + 1.0

    found = _line(f, 1.0 / WIDTH_RATIO, WIDTH_RATIO)
    assert abs(found / 0.77 - 1.0) < 0.01 and len(calls) < 25
    edge = _line(lambda d: (np.log(d / 30.0)) ** 2, 4.0 / DECAY_RATIO, 4.0 * DECAY_RATIO)
    assert abs(edge / (4.0 * DECAY_RATIO) - 1.0) < 1e-9


def test_golden_steps_keep_the_better_end() -> None:
    x, fx = _golden_min(lambda v: (v - 0.3) ** 2, 0.0, 1.0, 30)
    assert abs(x - 0.3) < 1e-5 and fx < 1e-10


def _on_grid(inputs):
    """F_z = -0.15 W exp(-(r / L)^2 - dz / 4 L) from a source above: exactly the grid kernel above_g1L_e4L_1."""
    force, torque = np.zeros((inputs.n_samples, 3)), np.zeros((inputs.n_samples, 3))
    for src in inputs.sources:
        dz, r = -src.offsets_m[:, 2], np.hypot(src.offsets_m[:, 0], src.offsets_m[:, 1])
        L = src.vehicle.size_m
        force[:, 2] -= 0.15 * inputs.target.weight_N * np.where(dz > 0, np.exp(-((r / L) ** 2) - dz / (4 * L)), 0.0)
    return force, torque


@pytest.mark.slow
def test_a_hidden_kernel_on_the_grid_keeps_its_grid_scales(tmp_path) -> None:
    """The hidden force IS a grid kernel: the search's best scales differ from the grid's by noise alone, which
    the flights held out (each at the scales chosen without it) do not confirm: the grid term stays."""
    from tests.identify.test_discovery import _run

    result, _ = _run(tmp_path, _on_grid)
    kept = {e["feature"]: e for e in result.discovered if e["selected"]}
    assert "above_g1L_e4L_1" in kept, list(kept)
    searched = kept["above_g1L_e4L_1"]["refined"]
    assert searched is None or not searched["accepted"]


HIDDEN_LOWPASS_S = 0.283
"""A low-pass time constant between the grid's 0.2 and 0.4 s (ratio 1.41 from each), s."""
HIDDEN_LAG_S = 0.465
"""A delay between the grid's 0.38 and 0.57 s (ratio 1.22 and 1.23 from each), s."""
FOUND_WITHIN = 1.15
"""The refined time within this ratio of the hidden one, -: under the ratio of the nearer grid value (1.22 for the
lag, 1.41 for the low-pass), so a grid term or a search ending at its bracket's edge fails; five times the errors
the first runs found (0.456 s: 2 %, 0.275 s: 3 %), set after them."""


def _swept_jet(inputs) -> np.ndarray:
    """(N,) the jet kernel of the sources above times the relative horizontal speed (above_jet_rel_speed_xy_mps)."""
    zero = [(np.zeros((inputs.n_samples, 3)), np.zeros((inputs.n_samples, 3))) for _ in inputs.sources]
    return feature_matrix(inputs, zero, ["above_jet_rel_speed_xy_mps"])[:, 0]


def _lowpassed(inputs):
    """F_z = -0.4 W x above_jet_rel_speed_xy_mps through a first-order low-pass of 0.283 s."""
    force, torque = np.zeros((inputs.n_samples, 3)), np.zeros((inputs.n_samples, 3))
    force[:, 2] = -0.4 * inputs.target.weight_N * lowpass(_swept_jet(inputs), inputs.time_s, HIDDEN_LOWPASS_S)
    return force, torque


def _delayed(inputs):
    """F_z = -0.4 W x above_jet_rel_speed_xy_mps delayed by 0.465 s."""
    force, torque = np.zeros((inputs.n_samples, 3)), np.zeros((inputs.n_samples, 3))
    force[:, 2] = -0.4 * inputs.target.weight_N * lagged(_swept_jet(inputs), inputs.time_s, HIDDEN_LAG_S)
    return force, torque


def _one_time_term(result, kind: str) -> tuple[float, dict]:
    kept = [e for e in result.discovered if e["selected"]]
    timed = [(parse_time_name(e["feature"]), e) for e in kept]
    timed = [(p, e) for p, e in timed if p is not None]
    assert len(timed) == 1 and timed[0][0][:2] == ("above_jet_rel_speed_xy_mps", kind), [e["feature"] for e in kept]
    return timed[0][0][2], timed[0][1]


def test_a_hidden_lowpass_off_the_grid_is_kept_as_one_term_near_its_time_constant(tmp_path) -> None:
    """The grid keeps lp200ms (the nearer of 0.2 and 0.4 s); refined by flights held out, the kept copy's time
    constant lies within 15 % of the hidden 0.283 s, and the refinement passed the gain test against lp200ms."""
    from tests.identify.test_discovery import _run

    assert LOWPASS_TAUS_S[2] < HIDDEN_LOWPASS_S < LOWPASS_TAUS_S[3] and LOWPASS_RATIO == 2.0
    result, _ = _run(tmp_path, _lowpassed)
    seconds, entry = _one_time_term(result, "lp")
    assert abs(np.log(seconds / HIDDEN_LOWPASS_S)) < np.log(FOUND_WITHIN), seconds
    assert entry["refined"]["accepted"] and entry["refined"]["test"]["passed"], entry["refined"]


@pytest.mark.slow
def test_a_hidden_lag_between_two_grid_lags_is_kept_as_one_term(tmp_path) -> None:
    """The grid keeps BOTH neighbours of a 0.465 s lag (lag380ms + lag570ms, on main); searched as one term over
    their brackets, the two grid terms together are not better on the flights held out than one lag near 0.465 s,
    which replaces them."""
    from tests.identify.test_discovery import _run

    assert LAGS_S[5] < HIDDEN_LAG_S < LAGS_S[6] and abs(LAG_RATIO - 1.5) < 1e-9
    result, _ = _run(tmp_path, _delayed)
    seconds, entry = _one_time_term(result, "lag")
    assert abs(np.log(seconds / HIDDEN_LAG_S)) < np.log(FOUND_WITHIN), seconds
    refined = entry["refined"]
    assert refined["merged"] and refined["accepted"] and len(refined["replaces"]) == 2, refined
