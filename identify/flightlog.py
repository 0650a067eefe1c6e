"""Flight logs for ``proxplan identify``: readers, the canonical writer, quality checks, and the
manifest's flights and vehicles (the manifest file itself is read by :mod:`proxplan.identify.manifest`).

Two CSV layouts (plain or gzip, ``*.gz``) are read, told apart by their header line:

* ``neural-swarm`` — the original Neural-Swarm files (``../shared/data/neural-swarm/README.md``):
  ``# time[ms],x[m],...,u1[N]..u4[N],u1[PWM]..,wx[rad/s],..``. The ``time[ms]`` column counts
  **microseconds**; it is converted to seconds here.
* ``canonical`` — our own layout, written by :func:`write_canonical_csv` (documented in
  ``docs/identify.md``): ``t_s,x_m,y_m,z_m,vx_mps,vy_mps,vz_mps,ax_mps2,ay_mps2,az_mps2,qx,qy,qz,qw,
  f1_N,f2_N,f3_N,f4_N,wx_radps,wy_radps,wz_radps``.

Both map onto :class:`VehicleLog`. Frames: positions, velocities and the accelerometer reading
(specific force, +9.81 m/s^2 on z in hover) in the world frame, z up; the quaternion (x, y, z, w)
rotates body to world; the gyro is in the body frame; motor thrusts in (S0-14) order.

Quality checks (:func:`check_log`, :func:`load_flight`) never let a bad sample through silently:
missing columns and time going backwards are :class:`UserError` naming the file and the row; NaN
rows, gaps, ground contact and samples outside the time overlap of the flight's vehicles are
excluded and counted in :class:`Exclusions`; a flight whose vehicles do not overlap in time is a
UserError.
"""

from __future__ import annotations

import gzip
import io
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Literal, get_args

import numpy as np

from proxplan.fileio import UserError, atomic_write_bytes

CANONICAL_COLUMNS = (
    "t_s", "x_m", "y_m", "z_m", "vx_mps", "vy_mps", "vz_mps", "ax_mps2", "ay_mps2", "az_mps2",
    "qx", "qy", "qz", "qw", "f1_N", "f2_N", "f3_N", "f4_N", "wx_radps", "wy_radps", "wz_radps",
)  # fmt: skip
"""Header of the canonical CSV layout, in this order."""

NEURAL_SWARM_FILE_COLUMNS = (
    "time[ms]", "x[m]", "y[m]", "z[m]", "vx[m/s]", "vy[m/s]", "vz[m/s]", "ax[m/s^2]", "ay[m/s^2]", "az[m/s^2]",
    "qx", "qy", "qz", "qw", "u1[N]", "u2[N]", "u3[N]", "u4[N]", "u1[PWM]", "u2[PWM]", "u3[PWM]", "u4[PWM]",
    "Vbat[V]", "thrust_des[g]", "torquex[Nm]", "torquey[Nm]", "torquez[Nm]", "wx[rad/s]", "wy[rad/s]", "wz[rad/s]",
)  # fmt: skip
"""Every column of a Neural-Swarm log in file order (../shared/data/neural-swarm/README.md); the
header line is ``# `` followed by these names joined by commas."""

NEURAL_SWARM_COLUMNS = {
    "t_s": "time[ms]", "x_m": "x[m]", "y_m": "y[m]", "z_m": "z[m]",
    "vx_mps": "vx[m/s]", "vy_mps": "vy[m/s]", "vz_mps": "vz[m/s]",
    "ax_mps2": "ax[m/s^2]", "ay_mps2": "ay[m/s^2]", "az_mps2": "az[m/s^2]",
    "qx": "qx", "qy": "qy", "qz": "qz", "qw": "qw",
    "f1_N": "u1[N]", "f2_N": "u2[N]", "f3_N": "u3[N]", "f4_N": "u4[N]",
    "wx_radps": "wx[rad/s]", "wy_radps": "wy[rad/s]", "wz_radps": "wz[rad/s]",
}  # fmt: skip
"""Canonical name -> Neural-Swarm column name (the time column holds microseconds)."""

LogFormat = Literal["neural-swarm", "canonical", "usdlog", "rosbag", "ulog"]
"""The log formats a manifest may name: the CSV layouts read here, the binary ones by proxplan.identify.formats."""
FORMATS: tuple[str, ...] = get_args(LogFormat)


@dataclass(frozen=True)
class QualityOptions:
    """Thresholds of the log quality checks."""

    max_gap_s: float = 0.05  # a time step longer than this splits the log into segments, s
    min_segment_s: float = 0.5  # shorter segments are dropped (too short for derivatives), s
    ground_clearance_m: float = 0.03  # samples closer to the ground are ground contact, m
    min_thrust_fraction: float = 0.3  # total motor thrust below this x weight: motors idle/ground, -
    min_overlap_s: float = 1.0  # vehicles of a flight must share at least this much time, s
    impact_speed_mps: float = 0.3  # a ground contact entered descending faster than this is an impact, m/s
    impact_guard_s: float = 0.1  # samples this close (in time) to an impact are excluded too, s


@dataclass(frozen=True)
class Exclusions:
    """Counts of samples excluded by each quality check (reported, never silent)."""

    nan_rows: int = 0
    gap_segments: int = 0  # number of gaps found (each splits the log)
    short_segment_samples: int = 0
    ground_samples: int = 0
    outside_overlap_samples: int = 0
    impact_samples: int = 0  # airborne samples within impact_guard_s of a ground impact
    impacts: int = 0  # ground contacts entered faster than impact_speed_mps (counted, not samples)

    def total(self) -> int:
        return (self.nan_rows + self.short_segment_samples + self.ground_samples + self.outside_overlap_samples
                + self.impact_samples)  # fmt: skip

    def __add__(self, other: Exclusions) -> Exclusions:
        return Exclusions(*(a + b for a, b in zip(_fields(self), _fields(other))))

    def to_dict(self) -> dict[str, int]:
        return dict(zip(_FIELD_NAMES, _fields(self)))


_FIELD_NAMES = ("nan_rows", "gap_segments", "short_segment_samples", "ground_samples", "outside_overlap_samples",
                "impact_samples", "impacts")  # fmt: skip


def _fields(e: Exclusions) -> tuple[int, ...]:
    return tuple(getattr(e, k) for k in _FIELD_NAMES)


@dataclass(frozen=True)
class VehicleLog:
    """One vehicle's log over N samples (see the module docstring for frames and units)."""

    t_s: np.ndarray  # (N,) own clock, s
    position_m: np.ndarray  # (N, 3) world
    velocity_mps: np.ndarray  # (N, 3) world
    accel_mps2: np.ndarray  # (N, 3) accelerometer specific force rotated to world, m/s^2
    quat_xyzw: np.ndarray  # (N, 4) body -> world, scalar last
    motor_thrust_N: np.ndarray  # (N, 4) per-motor thrust, (S0-14) order
    gyro_radps: np.ndarray  # (N, 3) body rates, rad/s
    segment: np.ndarray = field(
        default_factory=lambda: np.zeros(0, dtype=int)
    )  # (N,) int: segment id (gaps split); empty = one segment
    source: str = ""
    motor_pwm: np.ndarray | None = None  # (N, 4) motor PWM command normalised 0..1, (S0-14) order; None: not logged
    vbat_V: np.ndarray | None = None  # (N,) battery voltage, V; None: not logged
    thrust_logged: bool = True  # False: the log holds no force; motor_thrust_N is the base map's force of
    # the PWM (scale 1, for the quality checks) until proxplan.identify.pwm_thrust puts the type's map in
    thrust_shape: str = ""  # base PWM map of a log without forces (proxplan.identify.pwm_thrust.SHAPES)

    def __post_init__(self) -> None:
        if self.segment.size != len(self.t_s):
            object.__setattr__(self, "segment", np.zeros(len(self.t_s), dtype=int))

    @property
    def has_pwm(self) -> bool:
        """True when motor PWM and battery voltage are logged (the delivered thrust can be measured)."""
        return self.motor_pwm is not None and self.vbat_V is not None

    def __len__(self) -> int:
        return len(self.t_s)

    def take(self, mask: np.ndarray) -> VehicleLog:
        """The samples where ``mask`` (N,) is True (or index array)."""
        return replace(
            self,
            **{k: getattr(self, k)[mask] for k in _ARRAYS},
            **{k: getattr(self, k)[mask] for k in _OPTIONAL_ARRAYS if getattr(self, k) is not None},
        )

    def as_table(self) -> np.ndarray:
        """(N, 21) array in :data:`CANONICAL_COLUMNS` order."""
        return np.column_stack([self.t_s, self.position_m, self.velocity_mps, self.accel_mps2,
                                self.quat_xyzw, self.motor_thrust_N, self.gyro_radps])  # fmt: skip


_ARRAYS = ("t_s", "position_m", "velocity_mps", "accel_mps2", "quat_xyzw", "motor_thrust_N", "gyro_radps", "segment")
_OPTIONAL_ARRAYS = ("motor_pwm", "vbat_V")

NEURAL_SWARM_PWM_COLUMNS = ("u1[PWM]", "u2[PWM]", "u3[PWM]", "u4[PWM]", "Vbat[V]")
"""Optional Neural-Swarm columns: normalised motor PWM (0..1) and battery voltage (V)."""
CANONICAL_PWM_COLUMNS = ("pwm1", "pwm2", "pwm3", "pwm4", "vbat_V")
"""Optional canonical columns (appended after :data:`CANONICAL_COLUMNS` when logged)."""


def _open_bytes(path: Path) -> bytes:
    try:
        if path.suffix == ".gz":
            with gzip.open(path, "rb") as fh:
                return fh.read()
        return path.read_bytes()
    except FileNotFoundError:
        raise UserError(f"{path}: log file not found") from None
    except (OSError, EOFError, UnicodeDecodeError) as err:
        raise UserError(f"{path}: cannot read log ({err})") from None


def _parse_numeric(body: bytes, path: Path, n_cols: int) -> np.ndarray:
    """Rows of comma-separated numbers -> (N, n_cols) float array (pandas' C parser)."""
    import pandas as pd

    try:
        data = pd.read_csv(io.BytesIO(body), header=None, dtype=float, engine="c").to_numpy()
    except pd.errors.EmptyDataError:
        data = np.zeros((0, n_cols))
    except (ValueError, TypeError, pd.errors.ParserError) as err:
        raise UserError(f"{path}: not a numeric CSV ({str(err).splitlines()[0]})") from None
    if data.shape[0] == 0 or data.shape[1] != n_cols:
        raise UserError(f"{path}: expected {n_cols} columns per row and at least one row")
    return data


def read_log(path: str | Path) -> VehicleLog:
    """Read one vehicle log (either layout, plain or .gz) without cleaning; UserError if unusable.

    NaN values are kept here; :func:`check_log` removes and counts them.
    """
    path = Path(path)
    raw = _open_bytes(path)
    header_b, _, body = raw.partition(b"\n")
    try:
        header = header_b.decode()
    except UnicodeDecodeError:
        raise UserError(f"{path}: header line is not text; expected a CSV header") from None
    names = [h.strip() for h in header.lstrip("#").strip().split(",")]
    if "time[ms]" in names:
        wanted, time_scale = NEURAL_SWARM_COLUMNS, 1e-6  # the column counts microseconds
        optional = NEURAL_SWARM_PWM_COLUMNS
    elif "t_s" in names:
        wanted, time_scale = {c: c for c in CANONICAL_COLUMNS}, 1.0
        optional = CANONICAL_PWM_COLUMNS
    else:
        raise UserError(
            f"{path}: not a flight log: expected a CSV whose header has 'time[ms]' (neural-swarm) or 't_s' "
            "(canonical), a Crazyflie uSD log (magic byte 0xBC), a PX4 ULog or a ROS 2 bag (see docs/identify.md)"
        )
    missing = [col for col in wanted.values() if col not in names]
    if missing:
        raise UserError(f"{path}: missing column(s) {', '.join(missing)}")
    data = _parse_numeric(body, path, len(names))
    col = {name: data[:, names.index(src)] for name, src in wanted.items()}

    def stack(*keys: str) -> np.ndarray:
        return np.column_stack([col[k] for k in keys])

    pwm = vbat = None
    if all(c in names for c in optional):  # else: no PWM/Vbat logged (callers fall back and say so)
        pwm = np.column_stack([data[:, names.index(c)] for c in optional[:4]])
        vbat = data[:, names.index(optional[4])]
    return VehicleLog(
        t_s=col["t_s"] * time_scale,
        position_m=stack("x_m", "y_m", "z_m"),
        velocity_mps=stack("vx_mps", "vy_mps", "vz_mps"),
        accel_mps2=stack("ax_mps2", "ay_mps2", "az_mps2"),
        quat_xyzw=stack("qx", "qy", "qz", "qw"),
        motor_thrust_N=stack("f1_N", "f2_N", "f3_N", "f4_N"),
        gyro_radps=stack("wx_radps", "wy_radps", "wz_radps"),
        source=str(path),
        motor_pwm=pwm,
        vbat_V=vbat,
    )


def write_canonical_csv(log: VehicleLog, path: str | Path) -> Path:
    """Write ``log`` in the canonical layout (gzip when the name ends in .gz), atomically."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    buf = io.StringIO()
    table, header = log.as_table(), list(CANONICAL_COLUMNS)
    if log.motor_pwm is not None and log.vbat_V is not None:
        table, header = np.column_stack([table, log.motor_pwm, log.vbat_V]), header + list(CANONICAL_PWM_COLUMNS)
    np.savetxt(buf, table, delimiter=",", header=",".join(header), comments="", fmt="%.9g")
    payload = buf.getvalue().encode()
    if path.suffix == ".gz":
        payload = gzip.compress(payload, mtime=0)
    return atomic_write_bytes(path, payload)


def impact_guard(
    t_s: np.ndarray, v_z_mps: np.ndarray, on_ground: np.ndarray, options: QualityOptions
) -> tuple[np.ndarray, int]:
    """Samples near a ground IMPACT (N,) bool, and the number of impacts.

    An impact is a ground contact (``on_ground`` (N,) bool, a run of it) entered descending faster than
    ``options.impact_speed_mps`` (m/s, world z up: ``v_z_mps`` (N,)) at some time within
    ``options.impact_guard_s`` before it. The samples within ``impact_guard_s`` before its first and
    after its last contact sample are guarded: the contact's force reaches them through the
    motion-capture latency and the measurement's smoothing window, and a bounce must not be smoothed
    into the flight around it. Slow touch-downs and take-offs are no impacts (nothing guarded).
    """
    n = len(t_s)
    guard = np.zeros(n, dtype=bool)
    if n == 0 or not on_ground.any():
        return guard, 0
    edges = np.diff(np.concatenate([[0], on_ground.astype(np.int8), [0]]))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)  # runs [start, stop)
    impacts = 0
    for a, b in zip(starts, stops):
        if a == 0:
            continue  # the log starts on the ground: a take-off
        before = (t_s >= t_s[a] - options.impact_guard_s) & (np.arange(n) < a)
        if not np.any(v_z_mps[before] < -options.impact_speed_mps):
            continue
        impacts += 1
        guard |= before
        guard |= (np.arange(n) >= b) & (t_s <= t_s[b - 1] + options.impact_guard_s)
    return guard, impacts


def check_log(
    log: VehicleLog, *, weight_N: float, ground_z_m: float = 0.0, options: QualityOptions = QualityOptions()
) -> tuple[VehicleLog, Exclusions]:
    """Clean one log: drop NaN rows, split at gaps, drop short segments and ground contact.

    Args:
        log: as read by :func:`read_log`.
        weight_N: the vehicle's weight (idle-motor check), N.
        ground_z_m: ground height in the log's world frame, m.
    Returns:
        The cleaned log (``segment`` numbers contiguous stretches) and the exclusion counts.
    Raises:
        UserError: time going backwards or repeating (names the file and the row).
    """
    t = log.t_s
    dt = np.diff(t)
    finite_t = np.isfinite(t)
    bad = np.flatnonzero(np.isfinite(dt) & (dt <= 0.0))
    if bad.size:
        i = int(bad[0]) + 1
        raise UserError(
            f"{log.source}: time goes backwards or repeats at data row {i + 1} "
            f"({t[i - 1]:.6f} s -> {t[i]:.6f} s); logs must have increasing time"
        )
    table = log.as_table()
    if log.motor_pwm is not None and log.vbat_V is not None:
        table = np.column_stack([table, log.motor_pwm, log.vbat_V])
    finite = finite_t & np.all(np.isfinite(table), axis=1)
    nan_rows = int((~finite).sum())
    log = log.take(finite)
    if len(log) < 2:
        raise UserError(f"{log.source}: fewer than 2 usable rows (NaN rows: {nan_rows})")
    # ground contact / idle motors (before segmenting, so they split segments too); a motor asked for a
    # negative force is off (its floor), so the idle test sums the desired forces clipped at zero
    on_ground = log.position_m[:, 2] - ground_z_m <= options.ground_clearance_m
    airborne = ~on_ground & (
        np.clip(log.motor_thrust_N, 0.0, None).sum(axis=1) > options.min_thrust_fraction * weight_N
    )
    ground = int((~airborne).sum())
    guard, n_impacts = impact_guard(log.t_s, log.velocity_mps[:, 2], on_ground, options)
    guard &= airborne
    airborne &= ~guard
    # segments: a new one starts after every gap and every excluded stretch
    step = np.diff(log.t_s)
    breaks = np.concatenate([[True], (step > options.max_gap_s)])
    gaps = int((step > options.max_gap_s).sum())
    breaks |= np.concatenate([[True], airborne[1:] & ~airborne[:-1]])
    seg = np.cumsum(breaks) - 1
    log = replace(log, segment=seg).take(airborne)
    short = 0
    if len(log):
        ids, counts = np.unique(log.segment, return_counts=True)
        keep = np.ones(len(log), dtype=bool)
        for sid, n in zip(ids, counts):
            m = log.segment == sid
            if log.t_s[m][-1] - log.t_s[m][0] < options.min_segment_s:
                keep &= ~m
                short += int(n)
        log = log.take(keep)
        _, seg = np.unique(log.segment, return_inverse=True)
        log = replace(log, segment=seg)
    return log, Exclusions(nan_rows=nan_rows, gap_segments=gaps, short_segment_samples=short, ground_samples=ground,
                           impact_samples=int(guard.sum()), impacts=n_impacts)  # fmt: skip


# --------------------------------------------------------------------------------------- manifest


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
) -> Flight:
    """Read, check and time-align the logs of one flight (each vehicle keeps its own clock).

    ``vehicles`` maps each vehicle name of the entry to its :class:`Vehicle`. Samples outside the
    time overlap of all the flight's vehicles are excluded (counted); no overlap is a UserError.
    """
    logs, excl, alignment = {}, {}, {}
    for v in entry.vehicles:
        raw, alignment[v.name] = reader(v) if reader is not None else (read_log(v.log), {})
        log, ex = check_log(raw, weight_N=vehicles[v.name].weight_N, ground_z_m=v.ground_z_m, options=options)
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


def interpolate_position_m(log: VehicleLog, t_s: np.ndarray) -> np.ndarray:
    """Position (M, 3), m, of ``log`` at times ``t_s`` (M,) on another vehicle's clock (linear)."""
    return np.column_stack([np.interp(t_s, log.t_s, log.position_m[:, k]) for k in range(3)])
