"""Several vehicles, one clock: a log's clock put on a motion-capture track's by cross-correlation.

Onboard logs (uSD, ULog) count time since boot, so two vehicles' logs do not share a clock. A ROS 2
bag stamps everything with the host's clock (shared); a manifest may give each log an offset
(``time_offset_s``); or, when a vehicle names a motion-capture track (``mocap_log``), the offset is
estimated here: both positions are resampled on a common grid of step ``dt`` (the finer of the two
median steps), differentiated (velocities: no constant offset between the two position frames
matters), and the velocity's cross-correlation summed over the axes that move peaks at the lag; a
parabola through the peak and its neighbours refines it below one step.

Estimated error: the spread of the per-axis peaks (each moving axis correlated alone; standard
deviation), never below half a step (the resolution of the grid); both reported.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from proxplan.fileio import UserError
from proxplan.identify.flightlog import VehicleEntry
from proxplan.identify.formats.registry import detect_format, read_vehicle_log
from proxplan.identify.vehicle_log import VehicleLog

MAX_LAG_S = 30.0
"""The search covers logs that start within this of the track's start (on their own clocks), s."""
MIN_SPEED_MPS = 1e-3
"""Below this RMS speed on every axis the track does not move (nothing to correlate), m/s."""
AXIS_SHARE = 0.1
"""An axis takes part when its RMS speed is at least this share of the fastest axis's, -: an axis that
barely moves correlates on noise, and its own peak would only widen the error estimate."""


@dataclass(frozen=True)
class Alignment:
    """Offset added to the log's clock to put it on the track's (s), its estimated error (s), the peak's
    normalised correlation (-) and the axes used."""

    offset_s: float
    error_s: float
    correlation: float
    axes: str

    def to_json(self) -> dict:
        return {"alignment": "mocap", "time_offset_s": self.offset_s, "alignment_error_s": self.error_s,
                "correlation": self.correlation, "axes": self.axes}  # fmt: skip


def _peak(corr: np.ndarray) -> float:
    k = int(np.argmax(corr))
    if 0 < k < len(corr) - 1:
        a, b, c = corr[k - 1], corr[k], corr[k + 1]
        den = a - 2 * b + c
        return k + (0.5 * (a - c) / den if den < 0 else 0.0)
    return float(k)


def estimate_offset(
    t_log: np.ndarray, p_log: np.ndarray, t_ref: np.ndarray, p_ref: np.ndarray, *, where: str
) -> Alignment:
    """Offset (s) that puts the log's positions ``p_log`` (N, 3) at ``t_log`` (N,) onto the track
    ``p_ref`` (M, 3) at ``t_ref`` (M,); UserError naming ``where`` when nothing moves."""
    from scipy.signal import correlate

    dt = float(min(np.median(np.diff(t_log)), np.median(np.diff(t_ref))))
    grid_log = np.arange(t_log[0], t_log[-1], dt)
    grid_ref = np.arange(t_ref[0], t_ref[-1], dt)
    v_log = np.gradient(np.column_stack([np.interp(grid_log, t_log, p_log[:, k]) for k in range(3)]), dt, axis=0)
    v_ref = np.gradient(np.column_stack([np.interp(grid_ref, t_ref, p_ref[:, k]) for k in range(3)]), dt, axis=0)
    rms = np.sqrt(np.mean(v_ref**2, axis=0))
    moving = [k for k in range(3) if rms[k] > MIN_SPEED_MPS and rms[k] >= AXIS_SHARE * rms.max()]
    if not moving:
        raise UserError(f"{where}: the motion-capture track does not move (RMS speed <= {MIN_SPEED_MPS} m/s on every "
                        "axis): no clock offset can be found by cross-correlation; give time_offset_s")  # fmt: skip
    max_lag = int(round(MAX_LAG_S / dt))

    def lag_of(axes: list[int]) -> tuple[float, float]:
        total = 0.0
        for k in axes:
            a, b = v_ref[:, k] - v_ref[:, k].mean(), v_log[:, k] - v_log[:, k].mean()
            total = total + correlate(a, b, mode="full") / (np.linalg.norm(a) * np.linalg.norm(b) + 1e-12)
        lags = np.arange(-(len(v_log) - 1), len(v_ref))  # lag L: ref[i] ~ log[i - L]
        keep = np.abs(lags) <= max_lag
        corr = np.asarray(total)[keep]
        j = _peak(corr)
        lag0 = lags[keep][0]
        return (lag0 + j) * dt, float(np.max(corr)) / len(axes)

    lag_s, peak = lag_of(moving)
    per_axis = [lag_of([k])[0] for k in moving]
    error = max(0.5 * dt, float(np.std(per_axis)) if len(per_axis) > 1 else 0.5 * dt)
    offset = lag_s + (grid_ref[0] - grid_log[0])
    return Alignment(offset_s=float(offset), error_s=error, correlation=peak, axes="".join("xyz"[k] for k in moving))


def read_track(path) -> tuple[np.ndarray, np.ndarray]:
    """A motion-capture track: times (N,) s and positions (N, 3) m, world frame. A CSV whose header
    holds ``t_s,x_m,y_m,z_m`` (other columns ignored), or any log identify reads (its position)."""
    import gzip
    from pathlib import Path

    import pandas as pd

    path = Path(path)
    if detect_format(path) == "csv":
        opener = gzip.open if path.suffix == ".gz" else open
        try:
            with opener(path, "rt") as fh:
                head = [h.strip() for h in fh.readline().lstrip("#").split(",")]
        except (OSError, UnicodeDecodeError) as err:
            raise UserError(f"{path}: cannot read the motion-capture track ({err})") from None
        if {"t_s", "x_m", "y_m", "z_m"} <= set(head) and "f1_N" not in head:
            data = pd.read_csv(path, usecols=["t_s", "x_m", "y_m", "z_m"]).to_numpy(dtype=float)
            return data[:, 0], data[:, 1:4]
    log = read_vehicle_log(VehicleEntry(name="mocap", type="", log=path))
    return log.t_s, log.position_m


def align_log(log: VehicleLog, entry: VehicleEntry) -> tuple[VehicleLog, dict]:
    """``log`` on the flight's clock, and how (reported per vehicle): its own / the bag's clock plus the
    manifest's ``time_offset_s`` (already added by the reader), or shifted onto its ``mocap_log`` track
    by cross-correlation (offset and estimated error)."""
    if entry.mocap_log is None:
        how = "manifest offset" if entry.time_offset_s else "log clock"
        return log, {"alignment": how, "time_offset_s": entry.time_offset_s, "alignment_error_s": None}
    t_ref, p_ref = read_track(entry.mocap_log)
    ok = np.all(np.isfinite(log.position_m), axis=1) & np.isfinite(log.t_s)
    found = estimate_offset(log.t_s[ok], log.position_m[ok], t_ref, p_ref, where=str(entry.mocap_log))
    return replace(log, t_s=log.t_s + found.offset_s), found.to_json()


def read_aligned(entry: VehicleEntry, manifest_format: str = "") -> tuple[VehicleLog, dict]:
    """:func:`proxplan.identify.formats.registry.read_vehicle_log` then :func:`align_log`."""
    return align_log(read_vehicle_log(entry, manifest_format), entry)
