"""One vehicle's flight log (:class:`VehicleLog`) and the CSV layouts it is read from and written to
(the binary formats are read by :mod:`proxplan.identify.formats`).

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

Reading never cleans: NaN rows are kept; :mod:`proxplan.identify.log_checks` removes and counts them.
"""

from __future__ import annotations

import gzip
import io
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Literal, get_args

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


def interpolate_position_m(log: VehicleLog, t_s: np.ndarray) -> np.ndarray:
    """Position (M, 3), m, of ``log`` at times ``t_s`` (M,) on another vehicle's clock (linear)."""
    return np.column_stack([np.interp(t_s, log.t_s, log.position_m[:, k]) for k in range(3)])
