"""Crazyflie export: every vehicle of a plan as ``uav_trajectories`` CSV files (piecewise 7th-order
polynomials, C2 at every joint, <= 31 pieces an upload) and the manifest that lets ``proxplan
verify`` re-check the exported folder (:func:`planfile.read_export`).

By default each vehicle is one upload; when its plan needs more than
:data:`planfile.CRAZYFLIE_MAX_PIECES` pieces within the tolerance the export fails with
:class:`DoesNotFitError` naming the vehicle, the pieces and the deviation. With ``split_time`` the
trajectory is instead cut in time into consecutive uploads of at most :data:`SPLIT_PART_PIECES`
pieces, so that the next part fits into the other half of the trajectory memory while one flies
(double buffering: part k at piece offset ``(k % 2) * 16``, trajectory id ``k % 2``).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from export.polyfit import PieceFit, adaptive_fit, fit_ok
from fileio import atomic_write_text
from planfile import (
    CRAZYFLIE_MAX_PIECES,
    EXPORT_FORMAT,
    EXPORT_FORMAT_VERSION,
    EXPORT_MANIFEST,
    Plan,
    PolynomialTrajectory,
    Scenario,
    VehicleTrajectory,
    jsonable,
    plan_to_dict,
    trajectory_to_csv,
)

DEFAULT_TOLERANCE_M = 0.005  # fit target: half the 1 cm the export promises, m
SPLIT_PART_PIECES = 15  # pieces per upload with split_time (two uploads fit the 31-piece memory)
SPLIT_PIECE_OFFSET = 16  # piece offset of odd-numbered parts


class DoesNotFitError(Exception):
    """A vehicle's trajectory needs more than the firmware's pieces within the tolerance."""

    def __init__(self, vehicle: str, fit: PieceFit, tolerance_m: float) -> None:
        self.vehicle, self.pieces = vehicle, fit.trajectory.n_pieces
        self.deviation_m, self.tolerance_m = fit.max_deviation_m, tolerance_m
        self.kinematic_ratio = fit.max_kinematic_ratio
        kin = (
            f" and exceed its speed/acceleration/jerk limits {self.kinematic_ratio:.2f}x"
            if self.kinematic_ratio > 1.0
            else ""
        )
        super().__init__(
            f"vehicle '{vehicle}': {self.pieces} pieces (the Crazyflie holds at most {CRAZYFLIE_MAX_PIECES}) still "
            f"deviate {1000 * self.deviation_m:.1f} mm from the plan (tolerance {1000 * tolerance_m:.1f} mm){kin}; "
            "re-run with --split-time to cut it into several uploads in time"
        )


@dataclass(frozen=True)
class ExportedPart:
    """One upload: its CSV file name, trajectory (plan time ``start_time_s``) and deviation bound, m."""

    file: str
    trajectory: PolynomialTrajectory
    max_deviation_m: float
    trajectory_id: int = 0
    piece_offset: int = 0


def _split(tr: VehicleTrajectory, fit: PieceFit, name: str, tolerance_m: float) -> list[ExportedPart]:
    """Cut an unlimited fit into consecutive uploads of <= SPLIT_PART_PIECES pieces (same polynomials)."""
    traj = fit.trajectory
    parts = []
    for k, first in enumerate(range(0, traj.n_pieces, SPLIT_PART_PIECES)):
        sl = slice(first, first + SPLIT_PART_PIECES)
        part = PolynomialTrajectory(traj.durations_s[sl], traj.coef[sl], float(traj.joints_s[first]))
        dev = float(fit.piece_deviation_m[sl].max())
        parts.append(ExportedPart(f"{name}_part{k + 1}.csv", part, dev, k % 2, (k % 2) * SPLIT_PIECE_OFFSET))
    return parts


def export_vehicle(
    tr: VehicleTrajectory,
    *,
    limits: tuple[float, float, float] | None,
    tolerance_m: float = DEFAULT_TOLERANCE_M,
    split_time: bool = False,
) -> list[ExportedPart]:
    """The uploads of one vehicle, within ``tolerance_m`` (m) of the plan and (with ``limits``:
    speed m/s, acceleration m/s^2, jerk m/s^3) within its kinematic limits as the verifier checks
    them; :class:`DoesNotFitError` when one upload cannot hold it and ``split_time`` is off (never a
    worse fit)."""
    t0, t1 = float(tr.t_s[0]), float(tr.t_s[-1])
    fit = adaptive_fit(tr, tolerance_m=tolerance_m, max_pieces=CRAZYFLIE_MAX_PIECES, t0_s=t0, t1_s=t1, limits=limits)
    if fit_ok(fit, tolerance_m, CRAZYFLIE_MAX_PIECES):
        return [ExportedPart(f"{tr.name}.csv", fit.trajectory, fit.max_deviation_m)]
    if not split_time:
        raise DoesNotFitError(tr.name, fit, tolerance_m)
    fit = adaptive_fit(tr, tolerance_m=tolerance_m, max_pieces=None, t0_s=t0, t1_s=t1, limits=limits)
    if not fit_ok(fit, tolerance_m):  # pieces hit the shortest allowed duration
        raise DoesNotFitError(tr.name, fit, tolerance_m)
    return _split(tr, fit, tr.name, tolerance_m)


def vehicle_limits(scenario: Scenario, name: str) -> tuple[float, float, float]:
    """(speed m/s, acceleration m/s^2, jerk m/s^3) limits the verifier checks vehicle ``name`` against."""
    task = scenario.vehicles[name]
    return (task.max_speed_mps, task.max_accel_mps2, task.max_jerk_mps3)


def export_crazyflie(
    plan: Plan,
    scenario: Scenario | None,
    folder: str | Path,
    *,
    tolerance_m: float = DEFAULT_TOLERANCE_M,
    split_time: bool = False,
    progress=None,
) -> dict:
    """Write every vehicle's CSV file(s) (kinematic limits from ``scenario``, none without one) and :data:`planfile.EXPORT_MANIFEST` into ``folder``;
    returns ``{vehicle: {type, files: [{file, pieces, max_deviation_m, start_time_s, ...}]}}``."""
    folder = Path(folder)
    parts_of = {}
    for name, tr in plan.vehicles.items():
        limits = vehicle_limits(scenario, name) if scenario is not None and name in scenario.vehicles else None
        parts_of[name] = export_vehicle(tr, limits=limits, tolerance_m=tolerance_m, split_time=split_time)
        if progress is not None:
            progress(name)
    summary = {}
    for name, parts in parts_of.items():
        files = []
        for part in parts:
            atomic_write_text(folder / part.file, trajectory_to_csv(part.trajectory))
            files.append(
                {
                    "file": part.file,
                    "pieces": part.trajectory.n_pieces,
                    "max_deviation_m": round(part.max_deviation_m, 6),
                    "start_time_s": part.trajectory.start_time_s,
                    "duration_s": part.trajectory.duration_s,
                    "trajectory_id": part.trajectory_id,
                    "piece_offset": part.piece_offset,
                }
            )
        summary[name] = {"type": plan.vehicles[name].type_name, "files": files}
    plan_doc = plan_to_dict(plan)
    plan_doc["vehicles"] = {}  # samples live in the CSVs
    manifest = {
        "format": EXPORT_FORMAT,
        "format_version": EXPORT_FORMAT_VERSION,
        "tolerance_m": tolerance_m,
        "vehicles": summary,
        "plan": plan_doc,
    }
    atomic_write_text(folder / EXPORT_MANIFEST, json.dumps(jsonable(manifest), indent=1))
    return summary
