"""Priority order of prioritised planning and conflict-driven re-ordering.

Initial order: hovering vehicles first (they never move), then the moving vehicles by decreasing
unobstructed flight time (the jerk-limited rest-to-rest minimum time of the straight line from start
to goal, or to the dock point, s; ties keep file order), with every dock target before the vehicles
docking to it. Long flights go first because they set the makespan and, in formation changes, they
cross the slots that shorter flights park in; a later vehicle can always wait at its start.

On failure, :func:`promote` moves the failed vehicle just before the vehicle that blocked it (named
by the most limiting constraint, e.g. "separation from v003"), or to the front of the moving
vehicles when the blocker was not planned before it; the plans of the vehicles in front of the
insertion point stay valid and are reused by the pipeline.
"""

from __future__ import annotations

import numpy as np

from proxplan.planfile import Scenario
from proxplan.planner.timing.durations import min_segment_duration_s


def unobstructed_time_s(scenario: Scenario, name: str) -> float:
    """Straight-line rest-to-rest minimum time of one vehicle's task (0 when hovering), s."""
    task = scenario.vehicles[name]
    if task.hover:
        return 0.0
    end = scenario.dock_geometry(name)[1] if task.dock_with is not None else task.goal_m
    assert end is not None
    return min_segment_duration_s(float(np.linalg.norm(end - task.start_m)), task.kinematic_limits)


def lower_bound_makespan_s(scenario: Scenario) -> float:
    """The largest unobstructed single-vehicle minimum time: no plan can finish earlier, s."""
    return max([unobstructed_time_s(scenario, n) for n in scenario.vehicles] + [0.0])


def respect_docks(scenario: Scenario, names: list[str]) -> list[str]:
    """``names`` reordered so that every dock target (among them) comes before its dockers."""
    out: list[str] = []

    def add(n: str) -> None:
        if n in out:
            return
        w = scenario.vehicles[n].dock_with
        if w is not None and w in names:
            add(w)
        out.append(n)

    for n in names:
        add(n)
    return out


def priority_order(scenario: Scenario) -> list[str]:
    """Hovering vehicles first, then the others longest unobstructed flight first (see module)."""
    hover = [n for n in scenario.dock_order() if scenario.vehicles[n].hover]
    moving = [n for n in scenario.vehicles if n not in hover]
    moving.sort(key=lambda n: -round(unobstructed_time_s(scenario, n), 6))  # stable: file order on ties
    return hover + respect_docks(scenario, moving)


def blocker_of(constraint: str | None, names: list[str]) -> str | None:
    """The other vehicle a constraint name points at ("downwash of v003" -> "v003"), if any."""
    if not constraint:
        return None
    last = constraint.split(" ")[-1]
    return last if last in names else None


def promote(scenario: Scenario, order: list[str], failed: str, constraint: str | None) -> tuple[list[str], int]:
    """New order after ``failed`` could not be planned; and how many leading vehicles keep their plans.

    The failed vehicle moves just before its blocker when that one was planned before it, else to
    the front of the moving vehicles; hovering vehicles stay first and dock targets before dockers.
    """
    hover = [n for n in order if scenario.vehicles[n].hover]
    moving = [n for n in order if n not in hover and n != failed]
    blocker = blocker_of(constraint, order)
    at = 0
    if blocker is not None and blocker in moving and order.index(blocker) < order.index(failed):
        at = moving.index(blocker)
    new = hover + respect_docks(scenario, moving[:at] + [failed] + moving[at:])
    keep = 0
    while keep < len(order) and new[keep] == order[keep]:
        keep += 1
    return new, keep
