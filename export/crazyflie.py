"""Crazyflie export: every vehicle of a plan as ``uav_trajectories`` CSV files (piecewise 7th-order
polynomials, C2 at every joint, <= 31 pieces an upload) and the manifest that lets ``proxplan
verify`` re-check the exported folder (:func:`proxplan.planfile.read_export`).

By default the upload compensates rotor drag (``drag_compensation``): it is the plan plus the lead
delta of :func:`proxplan.planfile.compensated_reference` (the vehicle's gains and drag, with the settle
tail after the plan's end), so that the vehicle, lagging its reference by what drag and its loop
lose, flies the plan; the manifest records how far each upload leads the plan and for how long its
tail runs, and ``proxplan verify`` on the folder checks the upload's predicted flight
(:func:`proxplan.planfile.read_export`). Without it the upload is the plan itself.

By default each vehicle is one upload; when its plan needs more than
:data:`proxplan.planfile.CRAZYFLIE_MAX_PIECES` pieces within the tolerance the export fails with
:class:`DoesNotFitError` naming the vehicle, the pieces and the deviation. With ``split_time`` the
trajectory is instead cut in time into consecutive uploads of at most :data:`SPLIT_PART_PIECES`
pieces, so that the next part fits into the other half of the trajectory memory while one flies
(double buffering: part k at piece offset ``(k % 2) * 16``, trajectory id ``k % 2``).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from proxplan.export.polyfit import PieceFit, adaptive_fit, fit_ok, fit_uniform
from proxplan.fileio import atomic_write_text
from proxplan.planfile import (
    CRAZYFLIE_MAX_PIECES,
    EXPORT_FORMAT,
    EXPORT_FORMAT_VERSION,
    EXPORT_MANIFEST,
    CompensatedReference,
    Plan,
    PolynomialTrajectory,
    Scenario,
    VehicleTrajectory,
    compensated_reference,
    jsonable,
    plan_to_dict,
    trajectory_to_csv,
)

DEFAULT_TOLERANCE_M = 0.002  # fit target, m: a fifth of the 1 cm promised, so an export flies within its tube
SPLIT_PART_PIECES = 15  # pieces per upload with split_time (two uploads fit the 31-piece memory)
SPLIT_PIECE_OFFSET = 16  # piece offset of odd-numbered parts


class DoesNotFitError(Exception):
    """A vehicle's trajectory needs more than the firmware's pieces within the tolerance:
    ``pieces`` the adaptive fit needed (or gave up at), ``deviation_m`` (m) and ``kinematic_ratio``
    of the best :data:`proxplan.planfile.CRAZYFLIE_MAX_PIECES`-piece fit."""

    def __init__(
        self, vehicle: str, needed: PieceFit, at_most: PieceFit, tolerance_m: float, what: str = "the plan"
    ) -> None:
        self.vehicle, self.pieces = vehicle, needed.trajectory.n_pieces
        self.deviation_m, self.tolerance_m = at_most.max_deviation_m, tolerance_m
        self.kinematic_ratio = at_most.max_kinematic_ratio
        found = "needs" if fit_ok(needed, tolerance_m) else "still misses with"
        over = 100 * (self.kinematic_ratio - 1)
        kin = f" and exceeds its speed/acceleration/jerk allowance by {over:.1f} %" if over > 0 else ""
        super().__init__(
            f"vehicle '{vehicle}' {found} {self.pieces} pieces to stay within {1000 * tolerance_m:.1f} mm of "
            f"{what} and its limits; with {at_most.trajectory.n_pieces} pieces (the Crazyflie holds at most "
            f"{CRAZYFLIE_MAX_PIECES}) it deviates {1000 * self.deviation_m:.1f} mm{kin}; "
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


def _split(
    tr: VehicleTrajectory,
    limits: tuple[float, float, float] | None,
    tolerance_m: float,
    t0_s: float,
    t1_s: float,
    what: str = "the plan",
    flown: bool = False,
) -> list[PieceFit]:
    """Consecutive fits of <= SPLIT_PART_PIECES pieces covering [t0_s, t1_s], s: a span that does not
    fit is halved at a plan sample time. Every part starts and ends in the plan's position,
    velocity and acceleration there, so consecutive uploads join C2."""
    fit = adaptive_fit(
        tr, tolerance_m=tolerance_m, max_pieces=SPLIT_PART_PIECES, t0_s=t0_s, t1_s=t1_s, limits=limits,
        flown=flown,
    )  # fmt: skip
    if fit_ok(fit, tolerance_m, SPLIT_PART_PIECES):
        return [fit]
    inner = tr.t_s[(tr.t_s > t0_s + 1e-9) & (tr.t_s < t1_s - 1e-9)]
    if inner.size == 0:
        raise DoesNotFitError(tr.name, fit, fit, tolerance_m, what)
    middle = float(inner[np.argmin(np.abs(inner - 0.5 * (t0_s + t1_s)))])
    halves = ((t0_s, middle), (middle, t1_s))
    return [fit for a, b in halves for fit in _split(tr, limits, tolerance_m, a, b, what, flown)]


def export_vehicle(
    tr: VehicleTrajectory,
    *,
    limits: tuple[float, float, float] | None,
    tolerance_m: float = DEFAULT_TOLERANCE_M,
    split_time: bool = False,
    lead: bool = False,
) -> list[ExportedPart]:
    """The uploads of one vehicle's reference ``tr`` (the plan, or with ``lead`` the plan + its drag
    lead), within ``tolerance_m`` (m) of it and (with ``limits``: speed m/s, acceleration m/s^2,
    jerk m/s^3) within the kinematic limits as the verifier checks them (for a lead: on the
    vehicle's predicted flight, :class:`proxplan.export.polyfit.FitTarget`);
    :class:`DoesNotFitError` when one upload cannot hold it and ``split_time`` is off (never a
    worse fit)."""
    t0, t1 = float(tr.t_s[0]), float(tr.t_s[-1])
    what = "the plan + drag lead (with its settle tail)" if lead else "the plan"
    fit = adaptive_fit(
        tr, tolerance_m=tolerance_m, max_pieces=CRAZYFLIE_MAX_PIECES, t0_s=t0, t1_s=t1, limits=limits, flown=lead
    )
    if fit_ok(fit, tolerance_m, CRAZYFLIE_MAX_PIECES):
        return [ExportedPart(f"{tr.name}.csv", fit.trajectory, fit.max_deviation_m)]
    uniform = fit_uniform(tr, CRAZYFLIE_MAX_PIECES, limits, tolerance_m, lead)  # sometimes beats the greedy
    if fit_ok(uniform, tolerance_m):
        return [ExportedPart(f"{tr.name}.csv", uniform.trajectory, uniform.max_deviation_m)]
    if not split_time:
        raise DoesNotFitError(tr.name, fit, uniform, tolerance_m, what)
    parts = []
    for k, part in enumerate(_split(tr, limits, tolerance_m, t0, t1, what, lead)):
        parts.append(
            ExportedPart(
                f"{tr.name}_part{k + 1}.csv", part.trajectory, part.max_deviation_m, k % 2, (k % 2) * SPLIT_PIECE_OFFSET
            )
        )
    return parts


def _lead_summary(ref: CompensatedReference) -> dict:
    """What the compensation did for one vehicle (manifest and JSON; SI units in the keys)."""
    vehicle = ref.trajectory.vehicle
    g = vehicle.controller
    return {
        "max_lead_m": round(ref.max_lead_m, 6),
        "tail_s": round(ref.tail_s, 3),
        "residual_m": round(ref.residual_m, 6),
        "drag_rate_ps": [round(float(c), 6) for c in vehicle.drag_rate_ps],
        "gains": {
            k: getattr(g, k) for k in ("kp_xy_Npm", "kd_xy_Nspm", "ki_xy_Npms", "kp_z_Npm", "kd_z_Nspm", "ki_z_Npms")
        },
        "motor_time_constant_s": vehicle.motor_time_constant_s,
    }


def vehicle_limits(plan: Plan, scenario: Scenario | None, name: str) -> tuple[float, float, float]:
    """(speed m/s, acceleration m/s^2, jerk m/s^3) limits the verifier checks vehicle ``name``
    against: its scenario task's, else its vehicle type's."""
    if scenario is not None and name in scenario.vehicles:
        task = scenario.vehicles[name]
        return (task.max_speed_mps, task.max_accel_mps2, task.max_jerk_mps3)
    lim = plan.vehicles[name].vehicle.kinematic_limits
    return (lim.max_speed_mps, lim.max_accel_mps2, lim.max_jerk_mps3)


def export_crazyflie(
    plan: Plan,
    scenario: Scenario | None,
    folder: str | Path,
    *,
    tolerance_m: float = DEFAULT_TOLERANCE_M,
    split_time: bool = False,
    drag_compensation: bool = True,
    progress=None,
) -> dict:
    """Write every vehicle's CSV file(s) (kinematic limits from ``scenario``, else from the vehicle
    types) and :data:`proxplan.planfile.EXPORT_MANIFEST` into ``folder``; returns ``{vehicle:
    {type, files: [{file, pieces, max_deviation_m, start_time_s, ...}], drag_compensation: {...}
    | None}}`` (module docstring)."""
    folder = Path(folder)
    parts_of = {}
    leads = {}
    for name, tr in plan.vehicles.items():
        target = tr
        if drag_compensation:
            ref = compensated_reference(tr)
            target = ref.trajectory
            leads[name] = _lead_summary(ref)
        parts_of[name] = export_vehicle(
            target,
            limits=vehicle_limits(plan, scenario, name),
            tolerance_m=tolerance_m,
            split_time=split_time,
            lead=drag_compensation,
        )
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
        summary[name] = {
            "type": plan.vehicles[name].type_name,
            "files": files,
            "drag_compensation": leads.get(name),
        }
    plan_doc = plan_to_dict(plan)
    plan_doc["vehicles"] = {}  # samples live in the CSVs
    manifest = {
        "format": EXPORT_FORMAT,
        "format_version": EXPORT_FORMAT_VERSION,
        "tolerance_m": tolerance_m,
        "drag_compensation": drag_compensation,
        "vehicles": summary,
        "plan": plan_doc,
    }
    atomic_write_text(folder / EXPORT_MANIFEST, json.dumps(jsonable(manifest), indent=1))
    return summary
