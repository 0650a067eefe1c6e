"""Timing: jerk-limited, state-to-state Ruckig segments (community edition, never Ruckig's
intermediate waypoints), waypoint paths timed with them, rest-to-rest duration tables, and the
common time grid of plan.json onto which timed paths are assembled into a plan.

Modules: :mod:`~proxplan.planner.timing.durations` (rest-to-rest minimum times),
:mod:`~proxplan.planner.timing.segments` (single Ruckig segments),
:mod:`~proxplan.planner.timing.corners` (runs through waypoints without stopping),
:mod:`~proxplan.planner.timing.arcs` (a smooth detour timed along its path, ``ArcMove``: import it from there),
:mod:`~proxplan.planner.timing.paths` (timed waypoint paths),
:mod:`~proxplan.planner.timing.plan_grid` (the common grid and plan assembly).
"""

from proxplan.planner.timing.corners import CORNER_DEVIATION_M, corner_speeds, through_run
from proxplan.planner.timing.durations import DurationTable, duration_table, min_segment_duration_s
from proxplan.planner.timing.paths import (
    TimedPath,
    common_grid,
    time_parameterize,
    time_parameterize_through,
)
from proxplan.planner.timing.plan_grid import DOCK_SPEED_FACTOR, DT_S, assemble_plan, moving_end_s, vehicle_arrival_s
from proxplan.planner.timing.segments import ruckig_segment, through_segment

__all__ = [
    "CORNER_DEVIATION_M",
    "DOCK_SPEED_FACTOR",
    "DT_S",
    "DurationTable",
    "TimedPath",
    "assemble_plan",
    "common_grid",
    "duration_table",
    "min_segment_duration_s",
    "moving_end_s",
    "corner_speeds",
    "through_run",
    "ruckig_segment",
    "through_segment",
    "time_parameterize",
    "time_parameterize_through",
    "vehicle_arrival_s",
]
