"""Synthetic flight logs in the Neural-Swarm column layout, plus a DESIGN.md section 6 manifest.

Per vehicle, ``<out>/<flight>/<vehicle>.csv.gz``, 100 Hz by default, with the header of the real
files (``../shared/data/neural-swarm/README.md``), in this order:

* ``time[ms]`` — like the real files, counts MICROseconds (since the plan start);
* ``x, y, z [m]`` — true position plus motion-capture noise; ``vx, vy, vz [m/s]`` — true velocity
  plus noise; world frame, z up;
* ``ax, ay, az [m/s^2]`` — the simulated IMU accelerometer (specific force, noise, bias) rotated into
  the world frame with the true attitude (about +9.81 on z in hover);
* ``qx, qy, qz, qw`` — true attitude, body to world;
* ``u1..u4 [N]`` — per-motor thrust k_eta omega^2 of the ACTUAL (lagged) rotor speeds, (S0-14) order
  (a perfect static calibration); with ``logged_thrust="commanded"`` the controller's command
  clipped to the motor range instead, as the real logs (PWM command through a static calibration):
  then the motor lag (``Vehicle.motor_time_constant_s``) shows in S0-11;
* ``u1..u4 [PWM]`` — normalised motor command, commanded thrust / max thrust per motor (0..1, the
  scale the real files hold);
* ``Vbat [V]`` — constant 4.0 V; ``thrust_des [g]`` — commanded collective thrust in grams-force;
* ``torquex..z [Nm]`` — commanded body moments; ``wx, wy, wz [rad/s]`` — simulated gyro, body frame.

Beside each log, ``<vehicle>_truth.csv.gz`` holds what was applied (not part of the layout, for
tests and evaluation): time in s, the external force (N) and torque (N m) applied in total and by
the base model alone, world frame.

The truth effects applied go to ``<out>/<flight>/truth.yaml`` (NOT into the manifest, so they stay
undeclared to ``proxplan identify``). The manifest ``<out>/manifest.yaml`` (``format: neural-swarm``, ``root: .``) lists every flight
written to ``<out>``; writing a flight again replaces its entry. Files are written to a temporary
name and renamed, so nothing half-written is left on failure.
"""

from __future__ import annotations

import gzip
import io
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from proxplan.fileio import UserError, atomic_write_bytes, read_yaml
from proxplan.identify import NEURAL_SWARM_FILE_COLUMNS
from proxplan.physics import GRAVITY_MPS2

NEURAL_SWARM_HEADER = "# " + ",".join(NEURAL_SWARM_FILE_COLUMNS)  # the layout identify reads
TRUTH_HEADER = (
    "t_s,fx_applied_N,fy_applied_N,fz_applied_N,tx_applied_Nm,ty_applied_Nm,tz_applied_Nm,"
    "fx_model_N,fy_model_N,fz_model_N,tx_model_Nm,ty_model_Nm,tz_model_Nm"
)
BATTERY_VOLTAGE_V = 4.0
SPLITS = ("train", "test")


def _csv_gz(header: str, table: np.ndarray) -> bytes:
    buf = io.StringIO()
    np.savetxt(buf, table, delimiter=",", header=header, comments="", fmt="%.10g")
    return gzip.compress(buf.getvalue().encode(), compresslevel=6, mtime=0)


LOGGED_THRUSTS = ("actual", "commanded")


def neural_swarm_table(
    record,
    *,
    rng: np.random.Generator,
    mocap_noise_std_m: float = 0.0005,
    velocity_noise_std_mps: float = 0.005,
    logged_thrust: str = "actual",
) -> np.ndarray:
    """The (M, 30) Neural-Swarm table of one :class:`proxplan.flightsim.simulate.VehicleRecord`."""
    if logged_thrust not in LOGGED_THRUSTS:
        raise UserError(f"logged_thrust: expected one of {', '.join(LOGGED_THRUSTS)}, got {logged_thrust!r}")
    m = record.t_s.size
    veh = record.vehicle
    pos = (
        record.position_m + rng.normal(scale=mocap_noise_std_m, size=(m, 3))
        if mocap_noise_std_m > 0
        else record.position_m
    )
    vel = (
        record.velocity_mps + rng.normal(scale=velocity_noise_std_mps, size=(m, 3))
        if velocity_noise_std_mps > 0
        else record.velocity_mps
    )
    acc_world = Rotation.from_quat(record.q_xyzw).apply(record.accel_meas_body_mps2)
    pwm = np.clip(record.cmd_motor_thrust_N / veh.max_thrust_per_rotor_N, 0.0, 1.0)
    thrust = record.motor_thrust_N
    if logged_thrust == "commanded":
        thrust = np.clip(record.cmd_motor_thrust_N, veh.min_motor_thrust_N, veh.max_thrust_per_rotor_N)
    return np.column_stack(
        [
            np.round(record.t_s * 1e6),
            pos,
            vel,
            acc_world,
            record.q_xyzw,
            thrust,
            pwm,
            np.full(m, BATTERY_VOLTAGE_V),
            record.cmd_thrust_N / GRAVITY_MPS2 * 1000.0,
            record.cmd_moment_Nm,
            record.gyro_meas_radps,
        ]
    )


def _truth_table(record) -> np.ndarray:
    return np.column_stack(
        [record.t_s, record.applied_force_N, record.applied_torque_Nm, record.model_force_N, record.model_torque_Nm]
    )


def _noisy_tables(result, *, seed: int | None, logged_thrust: str) -> dict[str, np.ndarray]:
    """Neural-Swarm tables of every vehicle with mocap/velocity noise drawn from one seeded stream."""
    opts = result.options
    rng = np.random.default_rng(opts.seed + 7919 if seed is None else seed)
    mocap = opts.mocap_noise_std_m if opts.imu_noise else 0.0
    veln = opts.velocity_noise_std_mps if opts.imu_noise else 0.0
    return {
        name: neural_swarm_table(
            rec, rng=rng, mocap_noise_std_m=mocap, velocity_noise_std_mps=veln, logged_thrust=logged_thrust
        )
        for name, rec in result.records.items()
    }


def _write_custom_vehicles(result, out: Path) -> str | None:
    """Write the flown vehicles that are not built-in types to ``out/vehicles.yaml``; its name
    relative to ``out`` (None when every vehicle is a built-in type)."""
    import yaml

    from proxplan.physics import BUILTIN_VEHICLES, vehicle_to_yaml_dict

    custom = {
        rec.type_name: rec.vehicle
        for rec in result.records.values()
        if BUILTIN_VEHICLES.get(rec.type_name) != rec.vehicle
    }
    if not custom:
        return None
    doc = {"vehicles": {name: vehicle_to_yaml_dict(v) for name, v in custom.items()}}
    atomic_write_bytes(out / "vehicles.yaml", yaml.safe_dump(doc, sort_keys=False).encode())
    return "vehicles.yaml"


def write_flight_logs(
    result,
    out_dir: str | Path,
    *,
    flight_name: str,
    split: str = "train",
    seed: int | None = None,
    vehicles_file: str | None = None,
    logged_thrust: str = "actual",
) -> Path:
    """Write every vehicle of ``result`` (a :class:`proxplan.flightsim.simulate.SimulationResult`) as a
    Neural-Swarm log under ``out_dir/flight_name/`` and add the flight to ``out_dir/manifest.yaml``
    (created when missing). ``vehicles_file`` (relative to the manifest) names custom vehicle types;
    when None and a flown vehicle is not a built-in type (or differs from it), its parameters are
    written to ``out_dir/vehicles.yaml`` and the manifest names that file. ``logged_thrust`` is "actual" (k_eta omega^2) or "commanded" (see the module docstring).
    Returns the manifest path."""
    import yaml

    if split not in SPLITS:
        raise UserError(f"split: expected one of {', '.join(SPLITS)}, got {split!r}")
    if not flight_name or "/" in flight_name or flight_name.startswith("."):
        raise UserError(f"flight_name: expected a plain name (no '/'), got {flight_name!r}")
    out = Path(out_dir)
    opts = result.options
    entry_vehicles = {}
    for name, table in _noisy_tables(result, seed=seed, logged_thrust=logged_thrust).items():
        rec = result.records[name]
        rel = f"{flight_name}/{name}.csv.gz"
        atomic_write_bytes(out / rel, _csv_gz(NEURAL_SWARM_HEADER, table))
        atomic_write_bytes(out / f"{flight_name}/{name}_truth.csv.gz", _csv_gz(TRUTH_HEADER, _truth_table(rec)))
        entry_vehicles[name] = {"type": rec.type_name, "log": rel, "ground_z_m": float(opts.ground_z_m)}
    if vehicles_file is None:
        vehicles_file = _write_custom_vehicles(result, out)
    manifest = out / "manifest.yaml"
    if manifest.exists():
        doc = read_yaml(manifest, what="manifest") or {}
        if not isinstance(doc, dict) or doc.get("format") != "neural-swarm":
            raise UserError(f"{manifest}: exists but is not a neural-swarm manifest; choose another --out")
    else:
        doc = {"format": "neural-swarm", "root": ".", "flights": []}
    if vehicles_file is not None:
        doc["vehicles_file"] = vehicles_file
    doc["motor_thrust"] = "commanded" if logged_thrust == "commanded" else "delivered"  # the u[N] column
    flights = [f for f in doc.get("flights", []) if f.get("name") != flight_name]
    flights.append({"name": flight_name, "split": split, "vehicles": entry_vehicles})
    # the truth applied stays out of the manifest (effects are undeclared to identification)
    atomic_write_bytes(
        out / flight_name / "truth.yaml", yaml.safe_dump(result.truth.to_dict(), sort_keys=False).encode()
    )
    doc["flights"] = flights
    atomic_write_bytes(manifest, yaml.safe_dump(doc, sort_keys=False).encode())
    return manifest


def vehicle_logs(result, *, logged_thrust: str = "actual", seed: int | None = None) -> dict:
    """The logs :func:`write_flight_logs` would write, in memory: ``{name: proxplan.identify.vehicle_log.VehicleLog}``
    (same noise for the same ``seed``; world-frame accelerometer, body gyro, (S0-14) thrusts)."""
    from proxplan.identify import VehicleLog

    out = {}
    for name, tab in _noisy_tables(result, seed=seed, logged_thrust=logged_thrust).items():
        out[name] = VehicleLog(
            t_s=tab[:, 0] * 1e-6,
            position_m=tab[:, 1:4],
            velocity_mps=tab[:, 4:7],
            accel_mps2=tab[:, 7:10],
            quat_xyzw=tab[:, 10:14],
            motor_thrust_N=tab[:, 14:18],
            gyro_radps=tab[:, 27:30],
            source=f"flightsim:{result.scenario}:{name}",
        )
    return out
