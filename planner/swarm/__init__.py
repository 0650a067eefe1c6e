"""Swarm planning: coordinate jointly on a lattice, fly in continuous time (``--method swarm``,
and ``optimized`` for formation changes of ``SWARM_MIN_VEHICLES`` or more).

Data flow, one module per job: :mod:`~proxplan.planner.swarm.problem` (agents, keep-outs, free
space; :mod:`~proxplan.planner.swarm.keepout`, its shipped undamped zones
:mod:`~proxplan.planner.swarm.zone_store`; pairs frozen at the starts or goals moved out first,
:mod:`~proxplan.planner.swarm.frozen`) -> :mod:`~proxplan.planner.swarm.assign` and
:mod:`~proxplan.planner.swarm.goals` (goals of interchangeable vehicles, their costs round the obstacles
:mod:`~proxplan.planner.swarm.obstacle_costs`) ->
:mod:`~proxplan.planner.swarm.straight` (straight lines, synchronised or kept; by type, the groups in
conflict passing together, :mod:`~proxplan.planner.swarm.passes` (a component's joint moves,
:mod:`~proxplan.planner.swarm.pass_moves`, placed in rounds, :mod:`~proxplan.planner.swarm.pass_rounds`; a joint
move placed, :mod:`~proxplan.planner.swarm.joint`;
its members staggered, :mod:`~proxplan.planner.swarm.stagger`; late vehicles hemming one another in passing
together, :mod:`~proxplan.planner.swarm.hemmed`), or the others yielding on corners
or arcs, :mod:`~proxplan.planner.swarm.yielding` with :mod:`~proxplan.planner.swarm.arc_timing`; the
choice among them, :mod:`~proxplan.planner.swarm.give_way`) ->
:mod:`~proxplan.planner.swarm.prioritised_stage` (prioritised planning in each order, within a count
budget; the pass with both wavefronts after it, :mod:`~proxplan.planner.swarm.heights`) by
:mod:`~proxplan.planner.swarm.priority` (one pass, with repairs and predictions, asked and answered in
:mod:`~proxplan.planner.swarm.priority_options`, in the order of :mod:`~proxplan.planner.swarm.priority_order`;
one vehicle at a
time, :mod:`~proxplan.planner.swarm.single`; waiting aside, :mod:`~proxplan.planner.swarm.holding`; on a level, routes raised over the others, :mod:`~proxplan.planner.swarm.raised`) along :mod:`~proxplan.planner.swarm.wave` routes timed by :mod:`~proxplan.planner.swarm.chain` against
:mod:`~proxplan.planner.swarm.occupancy` (the space-time hash of
:mod:`~proxplan.planner.swarm.tracks`), by groups (:mod:`~proxplan.planner.swarm.components`) ->
:mod:`~proxplan.planner.swarm.lattice`, :mod:`~proxplan.planner.swarm.sync`,
:mod:`~proxplan.planner.swarm.lacam`, :mod:`~proxplan.planner.swarm.lockstep` (the guaranteed
lattice plan), beside it :mod:`~proxplan.planner.swarm.levels` and
:mod:`~proxplan.planner.swarm.stacked` (types on levels of their own, each planned apart; a level where
prioritised planning gave up by :mod:`~proxplan.planner.swarm.lanes`, two-way lanes kept right) -> :mod:`~proxplan.planner.swarm.retime` (continuous re-timing) ->
:mod:`~proxplan.planner.swarm.makespan` (the latest vehicles planned again with those in their way) ->
:mod:`~proxplan.planner.swarm.plan` (the entry points; the stages in order in
:mod:`~proxplan.planner.swarm.stages`, re-timing and the repair in :mod:`~proxplan.planner.swarm.retime_stage`
and :mod:`~proxplan.planner.swarm.repair_stage`, what a plan hands on in :mod:`~proxplan.planner.swarm.hand_on`;
with the knobs of :mod:`~proxplan.planner.swarm.options`, handing on a :mod:`~proxplan.planner.swarm.stage`) and
:mod:`~proxplan.planner.swarm.info` (what they report, typed).
"""

from proxplan.planner.swarm.assign import Assignment, assign_by_type, assign_group
from proxplan.planner.swarm.info import LatticeInfo, MakespanRepairInfo, RetimeInfo, SwarmInfo
from proxplan.planner.swarm.lacam import Lacam, LacamResult
from proxplan.planner.swarm.lattice import Lattice, build_lattice
from proxplan.planner.swarm.options import SwarmOptions
from proxplan.planner.swarm.plan import SWARM_MIN_VEHICLES, swarm_timed
from proxplan.planner.swarm.problem import SwarmProblem, swarm_applicable, swarm_problem
from proxplan.planner.swarm.stage import SwarmStage
from proxplan.planner.swarm.sync import SyncTable, segment_conflict

__all__ = [
    "SWARM_MIN_VEHICLES",
    "Assignment",
    "Lacam",
    "LacamResult",
    "Lattice",
    "LatticeInfo",
    "MakespanRepairInfo",
    "RetimeInfo",
    "SwarmInfo",
    "SwarmStage",
    "SwarmOptions",
    "SwarmProblem",
    "SyncTable",
    "assign_by_type",
    "assign_group",
    "build_lattice",
    "segment_conflict",
    "swarm_applicable",
    "swarm_problem",
    "swarm_timed",
]
