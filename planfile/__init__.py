"""The two file contracts of planning: scenario YAML in (:class:`Scenario`) and plan.json out
(:class:`Plan`), each declared once (:class:`ScenarioFile`, :class:`PlanFile`: their JSON Schemas
are ``proxplan schema scenario|plan``) and read and validated in one place, plus the one trajectory
sampler every user of a plan shares (:meth:`VehicleTrajectory.sample`), and the reference a vehicle is
given to fly its plan (:func:`compensated_reference`: plan + rotor-drag lead) with its inverse
(:func:`predicted_path`).
"""

from proxplan.planfile.crazyflie import (
    CRAZYFLIE_MAX_PIECES,
    EXPORT_FORMAT,
    EXPORT_FORMAT_VERSION,
    EXPORT_MANIFEST,
    N_COEF,
    PREDICTED_FLIGHT_KEY,
    PolynomialTrajectory,
    is_export_folder,
    read_export,
    read_uav_csv,
    resample_step,
    trajectory_to_csv,
)
from proxplan.planfile.plan import (
    PLAN_FILENAME,
    PLAN_FORMAT_VERSION,
    Plan,
    SolverStats,
    VehicleTrajectory,
    jsonable,
    plan_from_dict,
    plan_path,
    plan_to_dict,
    read_plan,
    write_plan,
)
from proxplan.planfile.plan_model import PlanFile
from proxplan.planfile.reference import (
    LEAD_SUBSTEPS,
    CompensatedReference,
    compensated_reference,
    drag_feedforward_mps2,
    predicted_path,
)
from proxplan.planfile.scenario import INVALID_ZONE_RULES, Box, Limits, Scenario, VehicleTask
from proxplan.planfile.scenario_load import load_scenario, scenario_from_dict
from proxplan.planfile.scenario_model import MAX_VEHICLES, ScenarioFile

__all__ = [
    "PREDICTED_FLIGHT_KEY",
    "LEAD_SUBSTEPS",
    "CompensatedReference",
    "compensated_reference",
    "drag_feedforward_mps2",
    "predicted_path",
    "CRAZYFLIE_MAX_PIECES",
    "EXPORT_FORMAT",
    "EXPORT_FORMAT_VERSION",
    "EXPORT_MANIFEST",
    "N_COEF",
    "PolynomialTrajectory",
    "is_export_folder",
    "read_export",
    "read_uav_csv",
    "resample_step",
    "trajectory_to_csv",
    "INVALID_ZONE_RULES",
    "PLAN_FILENAME",
    "PLAN_FORMAT_VERSION",
    "Box",
    "Limits",
    "Plan",
    "PlanFile",
    "SolverStats",
    "MAX_VEHICLES",
    "Scenario",
    "ScenarioFile",
    "VehicleTask",
    "VehicleTrajectory",
    "jsonable",
    "load_scenario",
    "plan_from_dict",
    "plan_path",
    "plan_to_dict",
    "read_plan",
    "scenario_from_dict",
    "write_plan",
]
