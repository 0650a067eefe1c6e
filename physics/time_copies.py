"""Time copies of features: lagged and low-pass copies within time runs, and their names.

A wake takes time to travel down and a rotor to spin up, so an effect of another vehicle may follow its cause
late or smoothed. Every relative-motion feature of :data:`TIME_FEATURE_SOURCES` (the base prediction and each
kernel of :mod:`proxplan.physics.features`, with and without relative speeds) gets a delayed copy at each of
:data:`LAGS_S` and a first-order low-pass copy at each time constant of :data:`LOWPASS_TAUS_S`, named
``<stem>_lag<ms>ms_<unit>`` and ``<stem>_lp<ms>ms_<unit>`` (:func:`time_name`); a copy at any whole number of
milliseconds off those grids is a feature too (:func:`parse_time_name`: discovery refines a kept copy's delay
or time constant, issue 35).

Copies need a clock (``EffectInputs.time_s``); without it (cost maps, static checks) every sample is a steady
state and a copy equals the instantaneous value. Time runs are split where the clock does not advance or
jumps by more than :data:`MAX_GAP_S` (pooled or sub-sampled series): each run is delayed, filtered and
differentiated (:func:`offset_rate_mps`) on its own.
"""

from __future__ import annotations

import re

import numpy as np

LAG_S = 0.1
"""Delay of the lagged base prediction, s (order of the motor + wake transport time; set when the dictionary
was written, commit 9a2cf90, not tuned on a figure)."""

LOWPASS_TAU_S = 0.3
"""Time constant of the first-order low-pass copy of the base prediction, s (set with :data:`LAG_S`, not tuned on
a figure)."""

LAGS_S = tuple(round(0.05 * 1.5**k, 3) for k in range(8))
"""Delays of the lagged copies of every relative-motion feature: a geometric grid 0.05..0.85 s
(ratio 1.5, so any delay in range is within 25 % of one), s."""

LOWPASS_TAUS_S = tuple(round(0.05 * 2.0**k, 3) for k in range(5))
"""Time constants of the low-pass copies of every relative-motion feature: 0.05..0.8 s (ratio 2), s."""

MAX_GAP_S = 1.0
"""A clock step larger than this (or not positive) starts a new time run, s: far above any logged sample step
(milliseconds); set with :data:`LAG_S`, not tuned on a figure."""

TIME_FEATURE_SOURCES = (
    "base_fz_N", "base_tx_Nm", "base_ty_Nm", "base_fz_rel_speed_xy_Nmps", "above_jet_1",
    "above_jet_rel_speed_xy_mps", "above_jet_rel_v_z_mps", "above_jet_x_1", "above_jet_y_1", "above_stack_1",
    "above_core_1", "above_core_flat_1", "above_near_1", "below_near_1", "side_near_1",
    "below_jet_1", "below_jet_rel_v_z_mps", "below_core_1", "below_core_flat_1", "below_cushion_1",
    "side_near_rel_v_z_mps",
)  # fmt: skip
"""Relative-motion features (of :data:`proxplan.physics.features.FEATURE_NAMES`) that get lagged and low-pass
copies."""

TIME_KINDS = {"lag": LAGS_S, "lp": LOWPASS_TAUS_S}
"""The kinds of time copy (name marker -> its declared grid, s): ``lag`` a delay, ``lp`` a first-order low-pass's
time constant. A copy at any whole number of milliseconds is a feature (:func:`parse_time_name`); the dictionary
holds the grids."""

_TIME_NAME = re.compile(r"^(?P<stem>.+)_(?P<kind>lag|lp)(?P<ms>[1-9][0-9]*)ms_(?P<unit>[^_]+)$")
"""A name of :func:`time_name`'s form: stem, kind of :data:`TIME_KINDS`, whole milliseconds (> 0), unit."""


def time_name(feature: str, kind: str, seconds: float) -> str:
    """The name of ``feature``'s time copy of ``kind`` (:data:`TIME_KINDS`) at ``seconds`` (s, held to whole
    milliseconds): ``<stem>_<kind><ms>ms_<unit>``."""
    stem, unit = feature.rsplit("_", 1)
    return f"{stem}_{kind}{int(round(1000 * seconds))}ms_{unit}"


def parse_time_name(name: str) -> tuple[str, str, float] | None:
    """(source feature, kind ``"lag"`` or ``"lp"``, seconds) of a time copy named by :func:`time_name` of a
    feature of :data:`TIME_FEATURE_SOURCES` at any positive whole number of milliseconds (on the declared grids or
    off them); None for any other name."""
    m = _TIME_NAME.match(name)
    if m is None:
        return None
    source = f"{m['stem']}_{m['unit']}"
    if source not in TIME_FEATURE_SOURCES:
        return None
    return source, m["kind"], int(m["ms"]) / 1000.0


def time_doc(source: str, kind: str, seconds: float) -> str:
    """One line saying what the time copy of ``source`` of ``kind`` at ``seconds`` (s) is."""
    if kind == "lag":
        return f"{source} delayed by {seconds:g} s"
    return f"{source} through a first-order low-pass, tau {seconds:g} s"


def _runs(time_s: np.ndarray) -> list[slice]:
    """Contiguous time runs of ``time_s`` (see :data:`MAX_GAP_S`)."""
    dt = np.diff(time_s)
    cuts = np.flatnonzero((dt <= 0.0) | (dt > MAX_GAP_S)) + 1
    edges = np.concatenate([[0], cuts, [len(time_s)]])
    return [slice(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:]) if b > a]


def lagged(x: np.ndarray, time_s: np.ndarray | None, lag_s: float = LAG_S) -> np.ndarray:
    """``x`` (N,) delayed by ``lag_s`` within each time run (held at the run's first value)."""
    if time_s is None:
        return np.asarray(x, dtype=float).copy()
    out = np.empty(len(x))
    for s in _runs(time_s):
        t = time_s[s]
        out[s] = np.interp(t - lag_s, t, x[s])
    return out


def lowpass(x: np.ndarray, time_s: np.ndarray | None, tau_s: float = LOWPASS_TAU_S) -> np.ndarray:
    """First-order low-pass y' = (x - y) / tau of ``x`` (N,) within each time run, started at x[0]
    (exact discretisation for a step-wise constant input at the run's median clock step)."""
    # imported here: scipy.signal takes ~1 s of CPU to import, and most users of this module never filter
    from scipy.signal import lfilter

    x = np.asarray(x, dtype=float)
    if time_s is None:
        return x.copy()
    out = np.empty(len(x))
    for s in _runs(time_s):
        xs = x[s]
        dt_s = float(np.median(np.diff(time_s[s]))) if len(xs) > 1 else 0.0
        a = 1.0 - np.exp(-dt_s / tau_s)
        y, _ = lfilter([a], [1.0, a - 1.0], xs, zi=np.array([(1.0 - a) * xs[0]]))
        out[s] = y
    return out


def offset_rate_mps(offsets_m: np.ndarray, time_s: np.ndarray) -> np.ndarray:
    """Time derivative of ``offsets_m`` (N, 3) within each time run (zero on single-sample runs), m/s."""
    out = np.zeros_like(offsets_m, dtype=float)
    for s in _runs(time_s):
        if s.stop - s.start > 1:
            out[s] = np.gradient(offsets_m[s], time_s[s], axis=0)
    return out
