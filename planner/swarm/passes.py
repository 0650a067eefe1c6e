"""Conflicting vehicles pass together: each group of straight lines in conflict is flown as one joint
manoeuvre, every member bulging aside at once (issue 37 item 5; round 23S).

Where the synchronised straight step has conflicting pairs
(:func:`~proxplan.planner.swarm.straight.straight_step_conflicts`), the yielding stage
(:mod:`proxplan.planner.swarm.yielding`) times the vehicles of a pair one after the other: the first
is fixed before the second is timed, so two neighbours swapping slots head-on each need the whole
keep-out's reach aside, and a smooth detour (:class:`~proxplan.planner.timing.arcs.ArcMove`) that far
aside costs 1.39-1.41 B on grid-64 by type (B: the assignment's bound), against 1.11-1.18 B for each of
the two bulging half of it to its right (measured, round 23S). Here the vehicles of each connected group
of conflicting pairs (a *component*: a swap, a rotation of three, a line through a resting slot) are
timed together:

* the *joint moves* of a component (:func:`joint_moves`): every moving member on an arc bulging
  :data:`PASS_REACH_FACTORS` times the widest keep-out's horizontal reach aside, all to their right or
  all to their left (head-on partners then pass on opposite sides), or one member on its straight line
  and the others bulging; resting members rest, or step as far aside (away from the movers' bulge) and
  back, rest to rest, at a few offsets. All depart at one grid step; a joint move is used only where
  its members' tracks are conflict-free among themselves
  (:meth:`~proxplan.planner.swarm.occupancy.Occupancy.conflicting_agents`, asked when it is first
  tried), or made so by staggering its members' departures (:mod:`proxplan.planner.swarm.stagger`),
  and statically free (the joint move and its placement: :mod:`proxplan.planner.swarm.joint`); a component without any is timed one by one (below);
* every vehicle in no conflict flies its straight line at its own limits from t = 0; the components,
  longest line first, are placed at the earliest common departure the tracks fixed so far allow
  (:func:`place_joint`: holds at the start before it, at the goal after it, the flown samples,
  exactly as :func:`~proxplan.planner.swarm.arc_timing.time_arc` asks them), the earliest arrival over
  its joint moves kept; *late* vehicles are then timed one by one, as the yielding stage times its
  vehicles (:func:`~proxplan.planner.swarm.yielding.time_yielding`: waits, corners, arcs; else a wavefront
  route, :func:`~proxplan.planner.swarm.hemmed.late_track`, round 29S);
* rounds (at most :data:`MAX_PASS_ROUNDS`; every unit that cannot be placed is found in one round): the
  straight-flying vehicles hemming in a component that cannot be placed become late; a component
  hemmed in by placed ones only is placed first, and where it was already, its members become late; a
  placed plan whose components had to wait makes the straight-flying vehicles in their way late (as an
  option: one that then cannot be timed goes back on its line for good); a late vehicle hemmed in by
  placed ones only is placed first, once (pillar-64 by type: no plan before, 1.16 B with it; round
  24S); hemmed in again by late vehicles, it and they pass together where they have a joint move
  (:func:`~proxplan.planner.swarm.hemmed.merged_group`; round 29S: corridor-64 by type 1.90x -> 1.34x),
  else it ends the rounds (no move of the stage frees it; grid-256 spent 16 s of CPU for nothing before). Then, at most :data:`MAX_RAISES` times, the latest vehicle's component (or late
  vehicle) is placed first while that shortens the plan. The earliest plan placed is kept; with none
  the stage gives up (None) and says so.

A vehicle whose straight line leaves the static free space (through an obstacle) is in no component: it
is late from the start, timed round the obstacle through a corner beside its line's blocked stretch
(:func:`~proxplan.planner.swarm.yielding.around_obstacle`; round 24S: pillar-64 by type, 12 such lines,
1.83 B -> 1.16 B; timed late by the single-vehicle planner instead, corridor-64 and pillar-64 by type gave
up after 1.6 and 3.1 s of CPU, round 23S). The
yielding candidate does not try this stage inside the stacked plan's levels (the join re-times arcs
as corner chains: pillar-64 by type 1.83x -> 2.60x).

Every track is checked exactly against those placed before it (and the members of a component among
themselves), so the plan is conflict-free in the swarm layer's model; the verifier judges it as every plan.

This module is the stage's entry (:func:`passing_stage`: the lines through an obstacle timed first or not, the
shorter plan kept); the joint moves of a component are :mod:`proxplan.planner.swarm.pass_moves`, the placing
rounds :mod:`proxplan.planner.swarm.pass_rounds`.
"""

from __future__ import annotations

from proxplan.planner.swarm.joint import JointMove, place_joint
from proxplan.planner.swarm.pass_moves import (
    PASS_REACH_FACTORS,
    conflict_components,
    conflict_free,
    fitted,
    joint_moves,
)
from proxplan.planner.swarm.pass_rounds import MAX_PASS_ROUNDS, MAX_RAISES, makespan_step, passing_rounds
from proxplan.planner.swarm.problem import SwarmProblem
from proxplan.planner.swarm.through_first import through_first
from proxplan.planner.swarm.yielding import YieldResult

# re-exported: the stage's constants and its moves keep their import path from this module
__all__ = [
    "MAX_PASS_ROUNDS",
    "MAX_RAISES",
    "PASS_REACH_FACTORS",
    "JointMove",
    "conflict_components",
    "conflict_free",
    "fitted",
    "joint_moves",
    "passing_stage",
    "place_joint",
]


def passing_stage(
    problem: SwarmProblem,
    horizon_steps: int,
    pairs: list[tuple[int, int]],
    *,
    arrive_by: int | None = None,
) -> YieldResult:
    """The plan of the module (``horizon_steps``: grid steps a timing may use; ``pairs``: the straight
    step's conflicts; ``arrive_by``: only a plan whose every vehicle arrives by this step is of interest;
    None: any). ``YieldResult.yielders``: the vehicles in a component or late. Where lines through an
    obstacle meet one another's timings (:func:`~proxplan.planner.swarm.through_first.through_first`), the
    stage with them timed first, and the stage as before asked for a shorter plan than that one; the
    shorter kept."""
    if not pairs:
        return YieldResult(None, (), "no conflicting pair (the synchronised straight step is the plan)")
    through = {i for i, j in pairs if i == j and not problem.pinned[i]}  # lines through an obstacle: late
    pre = through_first(problem, horizon_steps, through, arrive_by)
    if pre is None:
        return passing_rounds(problem, horizon_steps, pairs, through, arrive_by, {})
    first = passing_rounds(problem, horizon_steps, pairs, through, arrive_by, pre)
    if first.stage is None:
        plain = passing_rounds(problem, horizon_steps, pairs, through, arrive_by, {})
        return plain if plain.stage is not None else YieldResult(None, plain.yielders, f"{plain.note}; {first.note}")
    shorter = makespan_step({tr.agent: tr for tr in first.stage.tracks}) - 1
    plain = passing_rounds(
        problem, horizon_steps, pairs, through, shorter if arrive_by is None else min(arrive_by, shorter), {}
    )
    return plain if plain.stage is not None else first
