"""The disturbance model (seed 000 section II) and everything about a vehicle.

Vehicles (:class:`Vehicle`: the one home of every vehicle fact), the built-in types and vehicle
YAML files, the downwash velocity field (S0-1, S0-2), the drag and thrust-change wrench on a vehicle
below another (S0-3..S0-8), controller-authority usage (DESIGN.md section 3), and the library of
effects beyond the base model. Cost maps, planner, verifier, simulator and identification all use
this one implementation.
"""

from proxplan.physics.authority import authority_usage, mixer_matrix, motor_thrusts_N, normalised_motor_map
from proxplan.physics.builtin_vehicles import BUILTIN_VEHICLES
from proxplan.physics.disturbance import (
    DEFAULT_OPTIONS,
    VALIDITY_FACTOR_L,
    ModelOptions,
    disturbance_wrench,
    invalid_zone_mask,
    oncoming_speed_per_rotor_mps,
    validity_mask,
)
from proxplan.physics.effects import (
    DISCOVERED_PREFIX,
    EFFECT_NAMES,
    EFFECT_STRENGTHS,
    PARAMETERS,
    TARGET_ONLY_EFFECTS,
    Effect,
    EffectInputs,
    SourceSample,
    base_wrench,
    base_wrench_per_source,
    default_effect,
    effect_wrench,
    total_wrench,
)
from proxplan.physics.features import CHANNELS, FEATURE_DOCS, FEATURE_NAMES, feature_matrix, term_formula
from proxplan.physics.model_file import (
    MODEL_FORMAT_VERSION,
    CalibratedModel,
    between_vehicle_effects,
    effects_from_list,
    effects_to_list,
    load_model_file,
    load_model_section,
    model_file_dict,
    model_from_dict,
    options_from_mapping,
    target_only_notes,
    vehicle_file_notes,
    write_model_file,
)
from proxplan.physics.propeller import AIR_DENSITY_KGPM3, PropellerSpec, derived_b_v
from proxplan.physics.room import Plane, plane_distances_m, planes_from_list
from proxplan.physics.stack import MAX_STACK_SHIELDING, intercepted_flux_fraction, shielding_factors
from proxplan.physics.vehicle_yaml import (
    load_vehicle_file,
    resolve_vehicle,
    vehicle_from_dict,
    vehicle_to_yaml_dict,
)
from proxplan.physics.vehicles import (
    DEFAULT_TRACKING_TUBE_M,
    GRAVITY_MPS2,
    MOTOR_DIRECTIONS_XY,
    MOTOR_YAW_SIGNS,
    TRACKING_COURSE,
    TUBE_BUDGET_M,
    TUBE_MARGIN_M,
    DownwashSpec,
    FrameSpec,
    KinematicLimits,
    TrackingMeasurement,
    Vehicle,
)
from proxplan.physics.velocity_field import FIELD_FORMS, centreline_speed_mps, downwash_speed_mps

__all__ = [
    "MAX_STACK_SHIELDING",
    "Plane",
    "plane_distances_m",
    "planes_from_list",
    "base_wrench_per_source",
    "intercepted_flux_fraction",
    "shielding_factors",
    "AIR_DENSITY_KGPM3",
    "BUILTIN_VEHICLES",
    "CHANNELS",
    "DEFAULT_OPTIONS",
    "DISCOVERED_PREFIX",
    "EFFECT_NAMES",
    "EFFECT_STRENGTHS",
    "FEATURE_DOCS",
    "FEATURE_NAMES",
    "FIELD_FORMS",
    "GRAVITY_MPS2",
    "MODEL_FORMAT_VERSION",
    "MOTOR_DIRECTIONS_XY",
    "MOTOR_YAW_SIGNS",
    "PARAMETERS",
    "TARGET_ONLY_EFFECTS",
    "VALIDITY_FACTOR_L",
    "CalibratedModel",
    "DownwashSpec",
    "Effect",
    "EffectInputs",
    "FrameSpec",
    "KinematicLimits",
    "TrackingMeasurement",
    "DEFAULT_TRACKING_TUBE_M",
    "TRACKING_COURSE",
    "TUBE_BUDGET_M",
    "TUBE_MARGIN_M",
    "ModelOptions",
    "PropellerSpec",
    "SourceSample",
    "Vehicle",
    "authority_usage",
    "base_wrench",
    "between_vehicle_effects",
    "centreline_speed_mps",
    "default_effect",
    "derived_b_v",
    "disturbance_wrench",
    "downwash_speed_mps",
    "effect_wrench",
    "feature_matrix",
    "effects_from_list",
    "effects_to_list",
    "load_model_file",
    "load_model_section",
    "load_vehicle_file",
    "mixer_matrix",
    "model_file_dict",
    "model_from_dict",
    "motor_thrusts_N",
    "normalised_motor_map",
    "oncoming_speed_per_rotor_mps",
    "options_from_mapping",
    "resolve_vehicle",
    "term_formula",
    "target_only_notes",
    "total_wrench",
    "validity_mask",
    "invalid_zone_mask",
    "vehicle_file_notes",
    "vehicle_from_dict",
    "vehicle_to_yaml_dict",
    "write_model_file",
]
