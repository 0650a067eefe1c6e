"""Crazyflie trajectories: the ``uav_trajectories`` CSV layout of piecewise 7th-order polynomials,
and an exported folder read back as a :class:`~proxplan.planfile.plan.Plan` so the verifier checks what
will fly.

CSV layout (one header line, one row per piece)::

    Duration,x^0,...,x^7,y^0,...,y^7,z^0,...,z^7,yaw^0,...,yaw^7

``Duration`` in s; coefficients in ascending power of the piece's local time t in [0, Duration] s,
giving position in m (world frame, z up) and yaw in rad. The Crazyflie firmware holds at most
:data:`CRAZYFLIE_MAX_PIECES` such pieces per trajectory (4 KiB trajectory memory, 132 B a piece).

An exported folder holds one CSV per vehicle (or per vehicle and time part) and a manifest
:data:`EXPORT_MANIFEST` naming, per vehicle, its type, its files and their start times (and, format 2,
what the drag compensation did), plus the plan's vehicle types, scenario and model settings
(plan.json without the samples). Reading it gives where the vehicles will fly: each upload is a
*reference* the vehicle lags (rotor drag against its position loop), so the polynomials are
sampled finely and the vehicle's predicted path (:func:`proxplan.planfile.reference.predicted_path`,
the vehicle's gains and drag from the manifest's vehicle types) is put on the plan's time grid
(:func:`resample_step`) and validated with the plan.json rules. For a drag-compensated upload that
path is the plan (within the fit tolerance); for an uncompensated one it is the plan lagging by the
drag; never the raw upload.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from proxplan.fileio import UserError, read_json, read_text
from proxplan.planfile.plan import Plan, plan_from_dict, plan_vehicle_types
from proxplan.planfile.reference import LEAD_SUBSTEPS, predicted_path

CRAZYFLIE_MAX_PIECES = 31
POLY_ORDER = 7
N_COEF = POLY_ORDER + 1
AXES = ("x", "y", "z", "yaw")
CSV_HEADER = "Duration," + ",".join(f"{a}^{k}" for a in AXES for k in range(N_COEF))
EXPORT_MANIFEST = "export.json"
EXPORT_FORMAT = "proxplan-crazyflie-export"
EXPORT_FORMAT_VERSION = 2
READABLE_EXPORT_VERSIONS = (1, 2)
"""Export manifests read: 2 (written; ``drag_compensation``) and 1 (uncompensated uploads)."""

PREDICTED_FLIGHT_KEY = "predicted_flight"
"""The metric :func:`read_export` sets on the plan it returns: its trajectories are the predicted
flight of the uploads (the reduced loop's lag), not a plan the vehicles are given to fly."""


@dataclass(frozen=True)
class PolynomialTrajectory:
    """Piecewise polynomial of order 7: ``durations_s`` (K,), s, and ``coef`` (K, 4, 8): axes x, y,
    z (m) and yaw (rad), coefficients of t^0..t^7 with t the piece's local time in s. Starts at
    ``start_time_s`` (s, plan time)."""

    durations_s: np.ndarray
    coef: np.ndarray
    start_time_s: float = 0.0

    @property
    def n_pieces(self) -> int:
        return int(self.durations_s.size)

    @property
    def duration_s(self) -> float:
        return float(self.durations_s.sum())

    @property
    def end_time_s(self) -> float:
        return self.start_time_s + self.duration_s

    @property
    def joints_s(self) -> np.ndarray:
        """Plan times (K + 1,), s, of the piece boundaries (first = start, last = end)."""
        return self.start_time_s + np.concatenate([[0.0], np.cumsum(self.durations_s)])

    def evaluate(self, t_s: np.ndarray | float, derivative: int = 0) -> np.ndarray:
        """The ``derivative``-th time derivative (M, 4) of (x, y, z, yaw) at plan times ``t_s``
        (M,), s; times outside the trajectory are clamped to its ends."""
        t = np.atleast_1d(np.asarray(t_s, dtype=float)) - self.start_time_s
        starts = np.concatenate([[0.0], np.cumsum(self.durations_s)[:-1]])
        k = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, self.n_pieces - 1)
        tau = np.clip(t - starts[k], 0.0, self.durations_s[k])
        powers = np.arange(N_COEF)
        factor = np.ones(N_COEF)
        for d in range(derivative):
            factor = factor * np.maximum(powers - d, 0)
        exps = np.maximum(powers - derivative, 0)
        basis = factor[None, :] * tau[:, None] ** exps[None, :]  # (M, 8)
        return np.einsum("mk,mak->ma", basis, self.coef[k])


def trajectory_to_csv(traj: PolynomialTrajectory) -> str:
    """The ``uav_trajectories`` CSV text of ``traj`` (header line + one row per piece)."""
    rows = [CSV_HEADER]
    for d, c in zip(traj.durations_s, traj.coef):
        rows.append(",".join([repr(float(d))] + [repr(float(x)) for x in c.reshape(-1)]))
    return "\n".join(rows) + "\n"


def read_uav_csv(path: str | Path, *, start_time_s: float = 0.0) -> PolynomialTrajectory:
    """Read a ``uav_trajectories`` CSV; UserError naming file and row on a malformed one."""
    text = read_text(path, what="uav_trajectories CSV")
    lines = [ln for ln in text.splitlines() if ln.strip()]
    if not lines or not lines[0].lower().startswith("duration"):
        raise UserError(f"{path}: expected a header line starting with 'Duration' ({CSV_HEADER[:30]}...)")
    width = 1 + len(AXES) * N_COEF
    rows = []
    for i, line in enumerate(lines[1:], start=2):
        try:
            values = [float(x) for x in line.split(",")]
        except ValueError:
            raise UserError(f"{path}: line {i}: expected {width} numbers separated by commas") from None
        if len(values) != width or not all(math.isfinite(v) for v in values):
            raise UserError(f"{path}: line {i}: expected {width} finite numbers (Duration + 4 x 8 coefficients)")
        if values[0] <= 0:
            raise UserError(f"{path}: line {i}: Duration: expected a positive number of seconds, got {values[0]}")
        rows.append(values)
    if not rows:
        raise UserError(f"{path}: expected at least one piece row after the header")
    data = np.asarray(rows)
    return PolynomialTrajectory(data[:, 0], data[:, 1:].reshape(-1, len(AXES), N_COEF), float(start_time_s))


def resample_step(dt_s: float) -> float:
    """Step of the grid an export is re-read on, s: the plan's own ``dt_s``, so the verifier's
    grid-based checks (consistency, jerk from finite differences) see the export at the resolution
    they saw the plan; its fine checks re-sample between the samples as for any plan."""
    return dt_s


def is_export_folder(path: str | Path) -> bool:
    """True when ``path`` is a folder holding an export manifest."""
    return (Path(path) / EXPORT_MANIFEST).is_file()


def _parts(entry: Any, where: str, folder: Path) -> list[PolynomialTrajectory]:
    if not isinstance(entry, dict) or not isinstance(entry.get("files"), list) or not entry["files"]:
        raise UserError(f"{where}.files: expected a non-empty list of {{file, start_time_s}}")
    parts = []
    for i, item in enumerate(entry["files"]):
        if not isinstance(item, dict) or not isinstance(item.get("file"), str):
            raise UserError(f"{where}.files[{i}]: expected {{file: NAME.csv, start_time_s: number}}")
        start = item.get("start_time_s", 0.0)
        if isinstance(start, bool) or not isinstance(start, (int, float)) or not math.isfinite(start):
            raise UserError(f"{where}.files[{i}].start_time_s: expected a number of seconds, got {start!r}")
        parts.append(read_uav_csv(folder / Path(item["file"]).name, start_time_s=float(start)))
    parts.sort(key=lambda p: p.start_time_s)
    return parts


def sample_parts(parts: list[PolynomialTrajectory], t_s: np.ndarray, derivatives: int = 3) -> list[np.ndarray]:
    """[position_m, velocity_mps, acceleration_mps2 (, jerk_mps3 ...)]: the first ``derivatives``
    time derivatives, each (M, 3), of consecutive uploads ``parts`` at plan times ``t_s`` (M,), s:
    each time is flown by the last part started by then; before the first and after the last part
    the vehicle rests at the end point."""
    t = np.asarray(t_s, dtype=float)
    starts = np.array([p.start_time_s for p in parts])
    which = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(parts) - 1)
    out = [np.zeros((t.size, 3)) for _ in range(derivatives)]
    for i, part in enumerate(parts):
        sel = which == i
        if not sel.any():
            continue
        for d in range(derivatives):
            value = part.evaluate(t[sel], d)[:, :3]
            if d:
                value[(t[sel] < part.start_time_s) | (t[sel] > part.end_time_s)] = 0.0
            out[d][sel] = value
    return out


def read_export(folder: str | Path) -> Plan:
    """Where an exported Crazyflie folder will fly (module docstring): every vehicle's predicted
    path under its uploads on the plan's uniform time grid, with the vehicle types, scenario and
    model settings of the manifest."""
    folder = Path(folder)
    label = str(folder / EXPORT_MANIFEST)
    doc = read_json(folder / EXPORT_MANIFEST, what="export manifest")
    if not isinstance(doc, dict) or doc.get("format") != EXPORT_FORMAT:
        raise UserError(f"{label}: format: expected {EXPORT_FORMAT!r} (a folder written by proxplan export)")
    if doc.get("format_version") not in READABLE_EXPORT_VERSIONS:
        raise UserError(
            f"{label}: format_version: expected one of {', '.join(map(str, READABLE_EXPORT_VERSIONS))}, "
            f"got {doc.get('format_version')!r}"
        )
    plan_doc = doc.get("plan")
    entries = doc.get("vehicles")
    if not isinstance(plan_doc, dict) or not isinstance(entries, dict) or not entries:
        raise UserError(f"{label}: plan / vehicles: expected the plan without samples and {{NAME: {{type, files}}}}")
    dt = plan_doc.get("dt_s")
    if isinstance(dt, bool) or not isinstance(dt, (int, float)) or not (dt > 0 and math.isfinite(dt)):
        raise UserError(f"{label}: plan.dt_s: expected a positive number of seconds, got {dt!r}")
    step = resample_step(float(dt))
    parts = {name: _parts(entry, f"{label}: vehicles.{name}", folder) for name, entry in entries.items()}
    end = max(p[-1].end_time_s for p in parts.values())
    t = np.arange(int(round(end / step)) + 1) * step
    first = min(0, int(np.floor(min(p[0].start_time_s for p in parts.values()) / step + 1e-9)))  # steps before 0
    fine = np.arange(first * LEAD_SUBSTEPS, int(round(end / step)) * LEAD_SUBSTEPS + 1) * (step / LEAD_SUBSTEPS)
    on_plan_grid = slice(-first * LEAD_SUBSTEPS, None, LEAD_SUBSTEPS)  # the vehicles fly from the first upload's start
    types = plan_vehicle_types(plan_doc, label)
    vehicles = {}
    for name, entry in entries.items():
        type_name = entry.get("type") if isinstance(entry, dict) else None
        if type_name not in types:
            raise UserError(
                f"{label}: vehicles.{name}.type: expected one of the plan's vehicle types ({', '.join(types)})"
            )
        p, v, a, j = sample_parts(parts[name], fine, derivatives=4)
        flown = predicted_path(fine, p, v, a, j, types[type_name])
        vehicles[name] = {"type": type_name, "t_s": t}
        for key, arr in zip(("position_m", "velocity_mps", "acceleration_mps2"), flown):
            vehicles[name][key] = arr[on_plan_grid]
    full = dict(plan_doc, dt_s=step, vehicles=vehicles)
    full["metrics"] = dict(plan_doc.get("metrics") or {}, **{PREDICTED_FLIGHT_KEY: True})
    full["notes"] = list(plan_doc.get("notes") or []) + [
        f"the predicted flight of the Crazyflie polynomials in {folder} (each vehicle lagging its uploads by its "
        f"rotor drag and loop, proxplan.planfile.reference.predicted_path), every {step:g} s"
    ]
    return plan_from_dict(full, label=label)
