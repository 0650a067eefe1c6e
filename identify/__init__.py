"""Closing the loop with flight data (DESIGN.md section 6): read flight logs and manifests, measure
the disturbance on every vehicle (S0-11, S0-13), calibrate the model's parameters on train flights,
try candidate effects, and report the error before and after on test flights. Logs: Neural-Swarm and
canonical CSV, Crazyflie uSD, ROS 2 bags, PX4 ULog (:mod:`proxplan.identify.formats`).
"""

from proxplan.identify.calibrate import VEHICLE_PARAMETERS, apply_vehicle_parameters
from proxplan.identify.discovery import DiscoveryOptions, discover_terms
from proxplan.identify.effect_selection import EffectSelector
from proxplan.identify.evaluate import EvaluationResult, evaluate_model, saved_model
from proxplan.identify.evaluate_report import write_evaluation_report
from proxplan.identify.flightlog import FlightEntry, Manifest, VehicleEntry, load_flight
from proxplan.identify.formats import describe_log, firmware_columns, manifest_skeleton, read_usdlog, write_usdlog
from proxplan.identify.manifest import ManifestFile, load_manifest
from proxplan.identify.measure import MeasuredWrench, MeasureOptions, measure_disturbance, measure_log
from proxplan.identify.pipeline import IdentifyOptions, IdentifyResult, run_identify
from proxplan.identify.report import write_report
from proxplan.identify.synthetic_logs import synthetic_logs, write_synthetic_manifest
from proxplan.identify.vehicle_log import (
    NEURAL_SWARM_COLUMNS,
    NEURAL_SWARM_FILE_COLUMNS,
    VehicleLog,
    read_log,
    write_canonical_csv,
)

__all__ = [
    "VEHICLE_PARAMETERS",
    "apply_vehicle_parameters",
    "NEURAL_SWARM_COLUMNS",
    "DiscoveryOptions",
    "EffectSelector",
    "NEURAL_SWARM_FILE_COLUMNS",
    "EvaluationResult",
    "FlightEntry",
    "IdentifyOptions",
    "IdentifyResult",
    "Manifest",
    "ManifestFile",
    "MeasureOptions",
    "MeasuredWrench",
    "VehicleEntry",
    "VehicleLog",
    "describe_log",
    "discover_terms",
    "firmware_columns",
    "manifest_skeleton",
    "read_usdlog",
    "write_usdlog",
    "evaluate_model",
    "load_flight",
    "load_manifest",
    "measure_disturbance",
    "measure_log",
    "read_log",
    "run_identify",
    "saved_model",
    "synthetic_logs",
    "write_canonical_csv",
    "write_evaluation_report",
    "write_synthetic_manifest",
    "write_report",
]
