"""Closed-loop flight of a plan on RotorPy's multirotor dynamics, flown by the Crazyflie firmware's
Mellinger controller (default; rate feed-forward from the reference jerk) or RotorPy's SE(3) law,
with the downwash of every other vehicle (and optional "truth" effects beyond the model) applied;
tracking reports, Neural-Swarm-layout flight logs of the simulated flights, and the measurement of
a vehicle type's trackable limits and tracking tube (``measure_tracking``).
"""

from proxplan.flightsim.identify_flights import HIDDEN_EFFECTS, simulated_swap_manifest
from proxplan.flightsim.logs import NEURAL_SWARM_HEADER, vehicle_logs, write_flight_logs
from proxplan.flightsim.mellinger import controller_gains, reference_body_rates
from proxplan.flightsim.options import CONTROLLERS, Perturbation, SimulationOptions
from proxplan.flightsim.records import SimulationResult, SimulationStatus, VehicleRecord
from proxplan.flightsim.report import (
    feedforward_comparison,
    plot_errors,
    predicted_deflection_m,
    record_tube_m,
    simulation_metrics,
    summary_dict,
)
from proxplan.flightsim.scenarios_synthetic import (
    battery_swap_plans,
    hover_stack_plan,
    single_hover_plan,
    swap_plan,
    takeoff_hover_plan,
    waypoint_trajectory,
)
from proxplan.flightsim.simulate import simulate_plan
from proxplan.flightsim.tracking import ERROR_QUANTILE, CourseFlight, TrackingResult, measure_tracking
from proxplan.flightsim.truth import TruthSpec, load_truth_file, merge_truth, model_truth, plan_truth, truth_from_dict

__all__ = [
    "HIDDEN_EFFECTS",
    "CONTROLLERS",
    "ERROR_QUANTILE",
    "CourseFlight",
    "TrackingResult",
    "controller_gains",
    "measure_tracking",
    "reference_body_rates",
    "NEURAL_SWARM_HEADER",
    "Perturbation",
    "SimulationOptions",
    "SimulationResult",
    "SimulationStatus",
    "TruthSpec",
    "VehicleRecord",
    "battery_swap_plans",
    "feedforward_comparison",
    "hover_stack_plan",
    "load_truth_file",
    "merge_truth",
    "model_truth",
    "plan_truth",
    "plot_errors",
    "predicted_deflection_m",
    "record_tube_m",
    "simulate_plan",
    "simulated_swap_manifest",
    "simulation_metrics",
    "single_hover_plan",
    "summary_dict",
    "swap_plan",
    "takeoff_hover_plan",
    "truth_from_dict",
    "vehicle_logs",
    "waypoint_trajectory",
    "write_flight_logs",
]
