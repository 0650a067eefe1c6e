"""The two file contracts of planning: scenario YAML in (:class:`Scenario`) and plan.json out
(:class:`Plan`), each read and validated in one place, plus the one trajectory sampler every user
of a plan shares (:meth:`VehicleTrajectory.sample`).
"""

from proxplan.planfile.crazyflie import (
    CRAZYFLIE_MAX_PIECES,
    EXPORT_FORMAT,
    EXPORT_FORMAT_VERSION,
    EXPORT_MANIFEST,
    N_COEF,
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
from proxplan.planfile.scenario import (
    INVALID_ZONE_RULES,
    MAX_VEHICLES,
    Box,
    Limits,
    Scenario,
    VehicleTask,
    load_scenario,
    scenario_from_dict,
)

__all__ = [
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
    "SolverStats",
    "MAX_VEHICLES",
    "Scenario",
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
