"""Independent verification of a plan against its scenario with the model evaluated directly
(the physics model, through proxplan.costmaps.pair_wrench for a calibrated model's effects, and the plan-file contract), and the predictions along a plan
(wrench, authority usage, invalid zone, separations) that planner metrics and the web app show, and
every vehicle's closed loop along the plan (its tube's growth by its tracking error along its own
reference and in the jets, whether it stays damped where it holds).
"""

from proxplan.verify.along import (
    WrenchAlongPlan,
    attach_feedforward,
    plan_samples,
    separation_summary,
    wrench_along_plan,
)
from proxplan.verify.checks import (
    GOAL_TOLERANCE_M,
    REST_SPEED_MPS,
    check_authority,
    check_authority_tube,
    check_pairs,
    scenario_of_plan,
    tube_offsets,
    verify_plan,
    verify_with_deflections,
)
from proxplan.verify.jet_loop import (
    LoopAlongPlan,
    check_jet_loop,
    deflection_along_plan,
    hold_poles,
    loop_along_plan,
)
from proxplan.verify.reach import MIN_DZ_M
from proxplan.verify.tracking import tracking_along_plan
from proxplan.verify.tube_growth import TubeGrowth, predicted_tube_growth
from proxplan.verify.violations import Violation

__all__ = [
    "GOAL_TOLERANCE_M",
    "MIN_DZ_M",
    "check_authority",
    "check_authority_tube",
    "check_pairs",
    "plan_samples",
    "LoopAlongPlan",
    "TubeGrowth",
    "check_jet_loop",
    "hold_poles",
    "loop_along_plan",
    "predicted_tube_growth",
    "REST_SPEED_MPS",
    "Violation",
    "WrenchAlongPlan",
    "attach_feedforward",
    "deflection_along_plan",
    "scenario_of_plan",
    "separation_summary",
    "tracking_along_plan",
    "tube_offsets",
    "verify_plan",
    "verify_with_deflections",
    "wrench_along_plan",
]
