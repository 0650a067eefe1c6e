"""Who gives way where interchangeable vehicles' straight lines conflict (issue 37 item 5): the shortest of the
vehicles passing together (:mod:`~proxplan.planner.swarm.passes`, tried first: its plan bounds the others' search)
and the two yielding modes of :mod:`~proxplan.planner.swarm.yielding` (the shorter line yields; every vehicle in a
conflict keeps right). Its own module because :mod:`~proxplan.planner.swarm.passes` builds on the yielding
module's timing: the choice among them imports both.
"""

from __future__ import annotations

from proxplan.planner.swarm.passes import passing_stage
from proxplan.planner.swarm.problem import SwarmProblem
from proxplan.planner.swarm.stage import Stage
from proxplan.planner.swarm.straight import straight_step_conflicts
from proxplan.planner.swarm.tracks import GRID_DT_S
from proxplan.planner.swarm.yielding import ARC_REACH_FACTORS, YieldResult, yielding_stage

__all__ = ["yielding_candidate"]


def _stage(problem, horizon_steps, right_hand, arrive_by, pairs, arc_factors) -> YieldResult:
    return yielding_stage(
        problem, horizon_steps, right_hand=right_hand, arrive_by=arrive_by, pairs=pairs, arc_factors=arc_factors
    )


def yielding_candidate(
    problem: SwarmProblem,
    horizon_steps: int,
    extra: dict,
    *,
    shorter_than_s: float | None = None,
    pairs: list[tuple[int, int]] | None = None,
    arc_factors: tuple[float, ...] = ARC_REACH_FACTORS,
    together: bool = True,
) -> Stage | None:
    """The shortest of the vehicles passing together (:func:`~proxplan.planner.swarm.passes.passing_stage`,
    tried first where ``together``), :func:`~proxplan.planner.swarm.yielding.yielding_stage` with the shorter
    line of each pair yielding, and with every vehicle in a conflict keeping right (None where all give up),
    each asked for a plan shorter than ``shorter_than_s`` (s; the plan in hand) and than the best so far
    (``pairs``: the straight step's conflicts where already found; ``arc_factors``: as ``yielding_stage``);
    what each gave in ``extra["yielding"]``."""
    if pairs is None:
        pairs = straight_step_conflicts(problem)
    best: Stage | None = None
    said = []
    ways = [
        ("shorter line yields", lambda by: _stage(problem, horizon_steps, False, by, pairs, arc_factors)),
        ("keep right", lambda by: _stage(problem, horizon_steps, True, by, pairs, arc_factors)),
    ]
    if together:  # first: its plan bounds the others' search
        ways.insert(0, ("pass together", lambda by: passing_stage(problem, horizon_steps, pairs, arrive_by=by)))
    for label, way in ways:
        bound_s = shorter_than_s if best is None else max(tr.arrival_s for tr in best.tracks)
        got = way(None if bound_s is None else int(round(bound_s / GRID_DT_S)) - 1)
        if got.stage is None:
            said.append(f"{label}: {got.note}")
            continue
        makespan = max(tr.arrival_s for tr in got.stage.tracks)
        said.append(f"{label}: {makespan:.2f} s ({got.note})")
        if best is None or makespan < max(tr.arrival_s for tr in best.tracks):
            best = Stage(got.stage.tracks, got.stage.stage, f"{got.note}, {label}", got.stage.routes)
    before = extra.get("yielding")  # an earlier attempt's record (plan._plan: within the enough factor first)
    extra["yielding"] = "; ".join(([before] if before else []) + said)
    return best
