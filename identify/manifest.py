"""The manifest of ``proxplan identify`` / ``evaluate`` (DESIGN.md section 6), declared
(:class:`ManifestFile`) and read into a :class:`~proxplan.identify.flightlog.Manifest`::

    format: neural-swarm            # the column layout of the logs (neural-swarm | canonical)
    root: ../../shared/data/neural-swarm   # relative to this file
    vehicles_file: vehicles.yaml    # optional custom vehicle types, relative to this file
    motor_thrust: commanded         # optional: what the logs' per-motor thrust is (default by format)
    quality: {max_gap_s: 0.05}      # optional thresholds of the log quality checks
    planes: [{name: wall, point_m: [2, 0, 0], normal: [-1, 0, 0]}]   # optional walls / ceiling
    flights:
      - name: swap_sl_00
        split: train                # train | validation | test (validation: chooses, fits nothing)
        set: swap_sl                # optional experiment set (default: the name without _<run>)
        vehicles:
          cf51:  {type: crazyflie-2.1, log: swap_sl/cf51_00.csv.gz, ground_z_m: 0.05}
          cf101: {type: crazyflie-parrot, log: swap_sl/cf101_00.csv.gz, score: false}
"""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path
from typing import Annotated, Literal, get_args

from pydantic import Field, model_validator

from proxplan.fileio import (
    FileModel,
    Flag,
    Name,
    NonNegative,
    Number,
    Text,
    UserError,
    optional,
    problem,
    read_yaml,
    validate,
)
from proxplan.identify.flightlog import FlightEntry, Manifest, VehicleEntry
from proxplan.identify.log_checks import QualityOptions
from proxplan.identify.vehicle_log import FORMATS, LogFormat
from proxplan.physics import BUILTIN_VEHICLES, PlaneList, planes_from_parts

MotorThrust = Literal["commanded", "delivered"]
MOTOR_THRUSTS: tuple[str, ...] = get_args(MotorThrust)
"""What a log's per-motor thrust column holds: the firmware's *commanded* (desired) force, which the
motors deliver through their lag (Neural-Swarm's u[N]; real flight controllers log this), or the
force the rotors *deliver* (simulators logging k_eta omega^2)."""
DEFAULT_MOTOR_THRUST = {"neural-swarm": "commanded", "canonical": "delivered", "usdlog": "commanded",
                        "rosbag": "commanded", "ulog": "commanded"}  # fmt: skip
"""Per log format, what its thrust column holds when the manifest does not say (key ``motor_thrust``)."""

Text1 = Annotated[Text, Field(min_length=1)]


def set_of_flight(name: str) -> str:
    """Default experiment set of a flight: its name without a trailing ``_<run number>``."""
    return re.sub(r"_\d+$", "", name)


class ManifestVehicle(FileModel):
    """One vehicle of a flight: its type and log."""

    type: Text1 = Field(
        description="vehicle type: built-in (proxplan vehicles) or from vehicles_file",
        json_schema_extra={"examples": list(BUILTIN_VEHICLES)},
    )
    log: Text1 = Field(description="the vehicle's log file, relative to root")
    ground_z_m: Number = optional("ground height in the log's world frame, m (default 0)")
    score: Flag = optional("false: the log is a downwash source for the others only (default true)")
    time_offset_s: Number = optional("added to the log's clock to put it on the flight's clock, s (default 0)")
    topics: BagTopics | None = optional("ROS 2 bag topics of this vehicle (format rosbag)")
    mocap_log: Text1 = optional(
        "motion-capture track of this vehicle, relative to root (CSV t_s,x_m,y_m,z_m or any log): the log's clock "
        "is put on the track's by cross-correlating positions (offset and its error reported)"
    )


class LogDataTopic(FileModel):
    """A Crazyswarm2 LogDataGeneric topic: its name and the variables its ``values`` hold, in order."""

    topic: Text1 = Field(description="topic name, e.g. /cf1/log1")
    vars: Annotated[list[Text1], Field(min_length=1)] = Field(
        description="the logging config's vars of this topic, in order (e.g. [acc.x, acc.y, acc.z])"
    )


class BagTopics(FileModel):
    """The topics of one vehicle in a ROS 2 bag (each optional; what they lack comes from the log topics)."""

    pose: Text1 = optional("geometry_msgs/PoseStamped topic (Crazyswarm2's /cfN/pose): position and attitude")
    imu: Text1 = optional("sensor_msgs/Imu topic: body-frame specific force (m/s^2) and rates (rad/s)")
    log: list[LogDataTopic] = optional("crazyflie_interfaces/LogDataGeneric topics with their vars")


class ManifestFlight(FileModel):
    """One flight: its split and the vehicles that flew together."""

    name: Annotated[Name, Field(min_length=1)] = Field(description="flight name (unique in the manifest)")
    split: Literal["train", "validation", "test"] = Field(
        description="train (fitting), validation (chooses effects / eta / discovered terms, fits nothing; "
        "best another day's) or test (reporting only)"
    )
    set: Text1 = optional("experiment set for per-set reports (default: the name without _<run>)")
    vehicles: Annotated[dict[Name, ManifestVehicle], Field(min_length=1)] = Field(
        description="the vehicles of the flight by name"
    )


class QualityPart(FileModel):
    """Thresholds of the log quality checks (each optional; defaults in QualityOptions)."""

    max_gap_s: NonNegative = optional("a longer time step splits the log into segments, s (default 0.05)")
    min_segment_s: NonNegative = optional("shorter segments are dropped, s (default 0.5)")
    ground_clearance_m: NonNegative = optional("closer to the ground is ground contact, m (default 0.03)")
    min_thrust_fraction: NonNegative = optional("total motor thrust below this x weight: motors idle, - (default 0.3)")
    min_overlap_s: NonNegative = optional("least time the vehicles of a flight share, s (default 1)")
    impact_speed_mps: NonNegative = optional(
        "a ground contact entered faster than this is an impact, m/s (default 0.3)"
    )
    impact_guard_s: NonNegative = optional("samples this close to an impact are dropped too, s (default 0.1)")


class ManifestFile(FileModel):
    """A flight-log manifest for proxplan identify / evaluate."""

    format: LogFormat = optional(
        "format of the logs: neural-swarm or canonical CSV (told apart by the header), usdlog (Crazyflie uSD deck), "
        "rosbag (ROS 2 .mcap / sqlite3), ulog (PX4); binary ones are also detected (default neural-swarm)"
    )
    root: Text1 = Field(description="folder of the logs, relative to this file (or absolute)")
    vehicles_file: Text1 = optional("a vehicle file of custom types, relative to this file")
    vehicle_file: Text1 = optional("the same as vehicles_file (either spelling)")
    motor_thrust: MotorThrust = optional(
        "what the logs' per-motor thrust is: commanded (reaches the air through the motor lag) or "
        "delivered (default: commanded for neural-swarm, delivered for canonical)",
    )
    quality: QualityPart | None = optional("thresholds of the log quality checks")
    variables: dict[Text1, Text1] | None = optional(
        "log contract name -> the log's variable name, overriding the Crazyflie table (e.g. {vbat: pm.vbatMV})"
    )
    planes: PlaneList | None = optional("walls / ceiling of the room, for place-in-room features")
    flights: list[ManifestFlight] = Field(description="the flights, each train or test")

    @model_validator(mode="after")
    def _unique_flight_names(self) -> ManifestFile:
        seen: set[str] = set()
        for i, flight in enumerate(self.flights):
            if flight.name in seen:
                raise problem(f"duplicate flight name {flight.name!r}", at=f"flights.{i}.name")
            seen.add(flight.name)
        return self


def load_manifest(path: str | Path, *, require_train_and_test: bool = True) -> Manifest:
    """Read and validate a manifest YAML (DESIGN.md section 6).

    ``root`` is resolved relative to the directory of the manifest file (absolute paths are kept);
    each ``log`` is resolved relative to ``root``; ``vehicles_file`` relative to the manifest.
    """
    path = Path(path)
    where = str(path)
    doc = validate(ManifestFile, read_yaml(path, what="manifest"), label=where)
    fmt = doc.format or FORMATS[0]
    root = Path(doc.root)
    root = root if root.is_absolute() else (path.parent / root)
    if not root.is_dir():
        raise UserError(f"{where}: root: directory {root} not found (resolved relative to the manifest)")
    vfile = doc.vehicles_file or doc.vehicle_file
    quality = dataclasses.replace(
        QualityOptions(), **(doc.quality.model_dump(exclude_unset=True) if doc.quality else {})
    )
    flights = []
    for fl in doc.flights:
        entries = tuple(
            VehicleEntry(
                name=name,
                type=v.type,
                log=root / v.log,
                ground_z_m=float(v.ground_z_m or 0.0),
                score=v.score is not False,
                time_offset_s=float(v.time_offset_s or 0.0),
                mocap_log=None if v.mocap_log is None else root / v.mocap_log,
                variables=dict(doc.variables or {}),
                topics=None if v.topics is None else v.topics.model_dump(exclude_unset=True),
            )
            for name, v in fl.vehicles.items()
        )
        flights.append(
            FlightEntry(name=fl.name, split=fl.split, vehicles=entries, set=fl.set or set_of_flight(fl.name))
        )
    if not any(v.score for f in flights for v in f.vehicles):
        raise UserError(f"{where}: flights: every vehicle says 'score: false'; at least one must be scored")
    splits = {f.split for f in flights}
    if require_train_and_test and not {"train", "test"} <= splits:
        raise UserError(f"{where}: flights: need at least one train and one test flight, got {sorted(splits)}")
    return Manifest(
        path=path,
        format=fmt,
        root=root,
        flights=tuple(flights),
        vehicles_file=None if vfile is None else path.parent / vfile,
        quality=quality,
        motor_thrust=doc.motor_thrust or DEFAULT_MOTOR_THRUST.get(fmt, "commanded"),
        planes=planes_from_parts(doc.planes),
    )
