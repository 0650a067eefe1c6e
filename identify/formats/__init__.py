"""Flight-log formats beyond the CSV layouts: every reader returns the one
:class:`proxplan.identify.vehicle_log.VehicleLog` the pipeline consumes, so nothing downstream changes.

Public API: :func:`read_vehicle_log` (one manifest vehicle entry -> VehicleLog), :func:`detect_format`,
:data:`LOG_FORMATS`; the contract table :data:`CRAZYFLIE_VARIABLES` (:mod:`.contract`); the uSD
decoder and writer :func:`read_usdlog`, :func:`write_usdlog` (:mod:`.usdlog`); :func:`describe_log`
(what a log holds, for ``proxplan logs``, :mod:`.describe`); :func:`align_log` (a log's clock: its own,
the manifest's offset, or cross-correlated with a motion-capture track, :mod:`.align`).
"""

from proxplan.identify.formats.align import align_log, read_aligned
from proxplan.identify.formats.contract import CONTRACT, CRAZYFLIE_VARIABLES, firmware_columns
from proxplan.identify.formats.describe import describe_log, manifest_skeleton
from proxplan.identify.formats.registry import LOG_FORMATS, detect_format, read_vehicle_log
from proxplan.identify.formats.usdlog import UsdLog, read_usdlog, usdlog_bytes, write_usdlog

__all__ = [
    "CONTRACT",
    "CRAZYFLIE_VARIABLES",
    "LOG_FORMATS",
    "UsdLog",
    "align_log",
    "describe_log",
    "firmware_columns",
    "manifest_skeleton",
    "read_aligned",
    "detect_format",
    "read_usdlog",
    "read_vehicle_log",
    "usdlog_bytes",
    "write_usdlog",
]
