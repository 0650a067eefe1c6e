"""The manifest's flights and vehicles (:class:`Manifest`, :class:`FlightEntry`, :class:`VehicleEntry`) and
:func:`load_flight`, which reads, checks and time-aligns one flight. The manifest file itself is read by
:mod:`proxplan.identify.manifest`, one log by :mod:`proxplan.identify.vehicle_log`, and its checks are
:mod:`proxplan.identify.log_checks`.

:func:`load_flight` never lets a bad sample through silently: each log's quality checks exclude and count
(:class:`proxplan.identify.log_checks.Exclusions`), samples outside the time overlap of the flight's vehicles
are excluded and counted, and a flight whose vehicles do not overlap in time is a UserError.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from proxplan.fileio import UserError
from proxplan.identify.log_checks import Exclusions, QualityOptions, check_log
from proxplan.identify.vehicle_log import VehicleLog, read_log


@dataclass(frozen=True)
class VehicleEntry:
    """One vehicle of a flight in the manifest."""

    name: str  # e.g. cf51
    type: str  # vehicle type (built-in or from ``vehicles_file``)
    log: Path  # resolved log path
    ground_z_m: float = 0.0  # ground height in the log's world frame, m
    score: bool = True  # False: the log is a downwash source for the others only, never scored
    time_offset_s: float = 0.0  # added to the log's clock to put it on the flight's common clock, s
    variables: Mapping[str, str] | None = None  # contract name -> log variable overrides (identify.formats)
    topics: Mapping[str, Any] | None = None  # ROS 2 bag topics of this vehicle (identify.formats.rosbag)
    mocap_log: Path | None = None  # motion-capture track: the clock is aligned on it (identify.formats.align)


FLIGHT_SPLITS = ("train", "validation", "test")
"""What a flight is for (manifest key ``split``): TRAIN flights fit every parameter; VALIDATION flights
(optional; best another day's) choose what to keep — effects, the stack's eta, discovered terms —
and fit nothing; TEST flights only report."""


@dataclass(frozen=True)
class FlightEntry:
    name: str
    split: str  # one of FLIGHT_SPLITS
    vehicles: tuple[VehicleEntry, ...]
    set: str = ""  # experiment set the flight belongs to (reports per set); default: name without a trailing _<run>


@dataclass(frozen=True)
class Manifest:
    """DESIGN.md section 6 manifest, paths resolved."""

    path: Path
    format: str
    root: Path
    flights: tuple[FlightEntry, ...]
    vehicles_file: Path | None = None  # optional custom vehicle types (proxplan.physics.vehicle_yaml)
    quality: QualityOptions = QualityOptions()
    motor_thrust: str = (
        "commanded"  # what the logs' per-motor thrust is: one of proxplan.identify.manifest.MOTOR_THRUSTS
    )
    planes: tuple = ()  # proxplan.physics.room.Plane: walls / ceiling of the room (key ``planes``)


@dataclass(frozen=True)
class Flight:
    """A loaded, cleaned flight: every vehicle's log restricted to the common time span."""

    name: str
    split: str
    vehicles: Mapping[str, Any]  # vehicle name -> proxplan.physics.vehicles.Vehicle
    logs: Mapping[str, VehicleLog]
    ground_z_m: Mapping[str, float]
    exclusions: Mapping[str, Exclusions]
    alignment: Mapping[str, dict] = field(default_factory=dict)  # vehicle -> how its clock was set (reported)


def load_flight(
    entry: FlightEntry,
    vehicles: Mapping[str, Any],
    *,
    options: QualityOptions = QualityOptions(),
    reader: Callable[[VehicleEntry], tuple[VehicleLog, dict]] | None = None,
    motor_time_constants_s: Mapping[str, float | None] | None = None,
) -> Flight:
    """Read, check and time-align the logs of one flight (each vehicle keeps its own clock).

    ``vehicles`` maps each vehicle name of the entry to its :class:`Vehicle`. Samples outside the
    time overlap of all the flight's vehicles are excluded (counted); no overlap is a UserError.
    ``motor_time_constants_s`` maps a vehicle name to its motors' lag where its logged thrust is commanded
    (s; :func:`check_log`'s idle test on the delivered thrust), absent or None where it is delivered.
    """
    logs, excl, alignment = {}, {}, {}
    for v in entry.vehicles:
        raw, alignment[v.name] = reader(v) if reader is not None else (read_log(v.log), {})
        tau = (motor_time_constants_s or {}).get(v.name)
        log, ex = check_log(raw, weight_N=vehicles[v.name].weight_N, ground_z_m=v.ground_z_m, options=options,
                            motor_time_constant_s=tau)  # fmt: skip
        if len(log) == 0:
            raise UserError(f"{v.log}: no usable samples after quality checks (ground/idle/NaN); flight {entry.name}")
        logs[v.name], excl[v.name] = log, ex
    t0 = max(log.t_s[0] for log in logs.values())
    t1 = min(log.t_s[-1] for log in logs.values())
    if len(logs) > 1 and t1 - t0 < options.min_overlap_s:
        spans = ", ".join(f"{n} {log.t_s[0]:.2f}-{log.t_s[-1]:.2f} s" for n, log in logs.items())
        raise UserError(
            f"flight {entry.name}: vehicles do not overlap in time ({spans}); need {options.min_overlap_s} s"
        )
    for name, log in list(logs.items()):
        inside = (log.t_s >= t0) & (log.t_s <= t1)
        logs[name] = log.take(inside)
        excl[name] = excl[name] + Exclusions(outside_overlap_samples=int((~inside).sum()))
    return Flight(
        name=entry.name,
        split=entry.split,
        vehicles=dict(vehicles),
        logs=logs,
        ground_z_m={v.name: v.ground_z_m for v in entry.vehicles},
        exclusions=excl,
        alignment=alignment,
    )
