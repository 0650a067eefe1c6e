"""Flyable files from a plan: Crazyflie ``uav_trajectories`` polynomials (C2, <= 31 pieces an upload,
within a position tolerance) and time-stamped set-points with the predicted downwash as
feed-forward, for streaming controllers. Plans are read only through ``planfile``."""

from proxplan.export.crazyflie import (
    DEFAULT_TOLERANCE_M,
    SPLIT_PART_PIECES,
    DoesNotFitError,
    ExportedPart,
    export_crazyflie,
    export_vehicle,
    vehicle_limits,
)
from proxplan.export.polyfit import PieceFit, adaptive_fit, deviation, fit_pieces
from proxplan.export.setpoints import (
    DEFAULT_RATE_HZ,
    SETPOINT_COLUMNS,
    export_setpoints,
    feedforward_wrench,
    setpoint_times,
)

__all__ = [
    "DEFAULT_RATE_HZ",
    "DEFAULT_TOLERANCE_M",
    "SETPOINT_COLUMNS",
    "SPLIT_PART_PIECES",
    "DoesNotFitError",
    "ExportedPart",
    "PieceFit",
    "adaptive_fit",
    "deviation",
    "export_crazyflie",
    "export_setpoints",
    "export_vehicle",
    "feedforward_wrench",
    "fit_pieces",
    "setpoint_times",
    "vehicle_limits",
]
