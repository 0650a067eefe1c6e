"""The swarm layer's complete stages without a prioritised search (issue 37; :mod:`proxplan.planner.swarm.plan`
runs them): every vehicle on its straight line in one synchronised step; LaCAM on the lattice flown in
lock-step (the guaranteed answer); the stacked plan's levels joined by vertical steps (each level planned
by a planner the caller passes in); the choice between the last two when prioritised planning gave up; and the choice between the prioritised
plan and the stacked plan made beside it (round 24B: pillar-64, where prioritised planning finds a plan)."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from proxplan.planner.errors import PlanNotFound
from proxplan.planner.swarm.info import LatticeInfo
from proxplan.planner.swarm.lacam import Lacam, LacamResult
from proxplan.planner.swarm.lattice import Lattice, build_lattice
from proxplan.planner.swarm.levels import Levels
from proxplan.planner.swarm.lockstep import lockstep_tracks
from proxplan.planner.swarm.options import SwarmOptions
from proxplan.planner.swarm.problem import SwarmProblem
from proxplan.planner.swarm.retime import route_chain
from proxplan.planner.swarm.stacked import StackedBound, stacked_bound, stacked_tracks
from proxplan.planner.swarm.stage import Stage, SwarmStage
from proxplan.planner.swarm.straight import straight_tracks
from proxplan.planner.swarm.sync import SyncTable
from proxplan.planner.swarm.tracks import GRID_DT_S, GridTrack

__all__ = [
    "BesideLevels",
    "gave_up",
    "join_levels",
    "lattice_stage",
    "stacked_beside",
    "stacked_while_shorter",
    "stacked_without_lattice",
    "stage_makespan",
    "straight_routes",
    "straight_stage",
]


def straight_routes(problem: SwarmProblem) -> Callable[[int], list[np.ndarray]]:
    return lambda a: [np.array([problem.starts_m[a], problem.goals_m[a]])]


def straight_stage(problem: SwarmProblem) -> Stage:
    """Every vehicle on its straight line in one synchronised step (no pair conflicts)."""
    straight = straight_tracks(problem, list(range(problem.n_agents)))
    tracks = [straight[a] for a in range(problem.n_agents)]
    return Stage(tracks, "straight", "one synchronised straight step", straight_routes(problem))


def stage_makespan(stage: Stage) -> float:
    return max(tr.arrival_s for tr in stage.tracks)


def lattice_stage(problem: SwarmProblem, opts: SwarmOptions, extra: dict, *, progress, deadline) -> Stage:
    """LaCAM on the lattice, flown in lock-step: the guaranteed answer (or PlanNotFound). LaCAM is run
    with up to ``opts.lattice_seeds`` seeds (``opts.seed`` + k) that SHARE one count budget
    (``opts.max_nodes`` configurations, ``opts.max_proposals`` proposals): the first search has all of it,
    as a single search had, and each further seed what the searches before it left; the plan whose
    lock-step tracks arrive first is kept (ties: the lower seed). A search that stops on what it was given
    spends the budget and ends the seeds; PlanNotFound only when the first one stops (its reason). So the
    stage never costs more than one search's budget (stop 58: four seeds with a budget each took grid-256
    past its 500 s CPU cap). A wall-clock ``deadline`` only ever stops it as "not found", so the plan kept
    never depends on the machine."""
    lattice = build_lattice(problem, max_run=opts.max_run)
    sync = SyncTable(problem.keepouts, problem.type_index, lattice.pos_mm)
    t1 = time.perf_counter()
    best: tuple[float, list[GridTrack], LacamResult] | None = None
    first_error: PlanNotFound | None = None
    makespans: list[str] = []
    nodes_left, proposals_left = opts.max_nodes, opts.max_proposals
    try:
        for k in range(opts.lattice_seeds):
            if k and (nodes_left <= 1 or (proposals_left is not None and proposals_left <= 0)):
                break  # the searches before spent the budget (the first one always runs)
            try:
                result = Lacam(lattice, sync, seed=opts.seed + k).solve(
                    max_nodes=nodes_left, max_proposals=proposals_left, deadline=deadline, progress=progress
                )
            except PlanNotFound as err:
                if deadline is not None and time.perf_counter() > deadline:
                    raise
                first_error = first_error or err
                makespans.append("not found")
                break
            nodes_left -= result.nodes
            if proposals_left is not None:
                proposals_left -= result.proposals
            tracks = lockstep_tracks(lattice, result.configurations)
            makespan = max(tr.arrival_s for tr in tracks)
            makespans.append(f"{makespan:.2f}")
            if best is None or makespan < best[0]:
                best = (makespan, tracks, result)
    finally:  # the search's closures keep the table until a full garbage collection: free its verdicts now
        sync.clear()
    if best is None:
        assert first_error is not None
        raise first_error
    _, tracks, result = best
    configurations = result.configurations
    extra["lattice"] = LatticeInfo(
        spacing_m=lattice.spacing_m,
        levels_m=lattice.levels_m.tolist(),
        vertices=int(lattice.pos_m.shape[0]),
        steps=len(configurations) - 1,
        nodes=result.nodes,
        tests=result.tests,
        time_s=round(time.perf_counter() - t1, 3),
    )

    def routes(a: int, lattice: Lattice = lattice) -> list[np.ndarray]:
        return [np.array([problem.starts_m[a], problem.goals_m[a]]), route_chain(lattice, configurations, a)]

    coordination = (
        f"LaCAM: {len(configurations) - 1} steps, {result.nodes} configurations, {result.tests} exact pair tests "
        f"(the first-arriving of {len(makespans)} seeds sharing one budget, lock-step makespans {', '.join(makespans)} s)"
    )
    return Stage(tracks, "lattice", coordination, routes)


def gave_up(lattice: Stage, stacked: Stage | None, opts: SwarmOptions, extra: dict) -> Stage:
    """The shorter of the lattice plan and the stacked plan (where one was made; ties: the lattice
    plan), saying why where prioritised planning ran and gave up."""
    found = stacked if stacked is not None and stage_makespan(stacked) < stage_makespan(lattice) else lattice
    if opts.prioritized:  # say why: prioritised planning gave up within its count budget
        spent = extra.get("counts", {}).get("planned", 0)
        found = replace(
            found, coordination=f"prioritised planning gave up ({spent} vehicle plannings); " + found.coordination
        )
    return found


def stacked_beside(prioritised: Stage, stacked: Stage | None, extra: dict) -> Stage:
    """The stacked plan made beside a prioritised plan where it is shorter before re-timing (ties: the
    prioritised plan; the rule :func:`gave_up` applies to the lattice plan), said in ``extra["stacked"]``."""
    if stacked is None:
        return prioritised
    mine, theirs = stage_makespan(stacked), stage_makespan(prioritised)
    keep = mine < theirs
    extra["stacked"] = f"{extra.get('stacked', '')}; beside the prioritised plan ({theirs:.2f} s): {mine:.2f} s, " + (
        "kept" if keep else "not kept"
    )
    if not keep:
        return prioritised
    return replace(stacked, coordination=f"shorter than the prioritised plan ({theirs:.2f} s); " + stacked.coordination)


LevelPlanner = Callable[[SwarmProblem], tuple[list[GridTrack], SwarmStage, int]]


@dataclass
class BesideLevels:
    """The planner of the stacked plan's levels where that plan is made beside a prioritised plan of
    makespan ``rival_s`` (s, before re-timing; :func:`stacked_beside` keeps the stacked plan only where
    strictly shorter), or beside the lattice plan (:func:`gave_up`, the same rule; ``rival``: which):
    each level planned by ``plan_level`` only while some stacked plan can still be
    shorter (:class:`~proxplan.planner.swarm.stacked.StackedBound` on ``levels``, with the makespans of
    the levels planned so far), else None (no later level is planned:
    :func:`~proxplan.planner.swarm.stacked.stacked_tracks`), said in ``stopped``. Exact: a plan stopped
    would have been at least as long as the prioritised plan, so not kept (round 25A: circle-64 made its
    stacked plan, 12.98 s, beside a prioritised plan of 11.53 s)."""

    problem: SwarmProblem
    levels: Levels | None
    rival_s: float
    plan_level: LevelPlanner
    rival: str = "the prioritised plan"  # what the stacked plan is weighed against, said in ``stopped``
    planned: int = 0  # levels planned
    planned_steps: int = 0  # the longest of their plans, grid steps
    stopped: str | None = None  # why no more levels were planned, None: not stopped
    _bound: StackedBound | None = field(default=None, repr=False)
    _bounded: bool = field(default=False, repr=False)

    def can_be_shorter(self) -> bool:
        """Whether some stacked plan can still be shorter than the prioritised plan (True where there is
        no stack or no vertical steps: the stacked plan says why it is not made)."""
        if self.levels is None:
            return True
        if not self._bounded:
            self._bound, self._bounded = stacked_bound(self.problem, self.levels), True
        if self._bound is None:
            return True
        least_s = self._bound.steps(self.planned_steps) * GRID_DT_S
        if least_s < self.rival_s:
            return True
        self.stopped = (
            f"not made beside {self.rival} ({self.rival_s:.2f} s): after {self.planned} of "
            f"{len(self.levels.groups)} levels planned, no stacked plan on levels "
            f"{'/'.join(f'{z:.2f}' for z in self.levels.heights_m)} m arrives before {least_s:.2f} s"
        )
        return False

    def __call__(self, sub: SwarmProblem) -> tuple[list[GridTrack], SwarmStage, int] | None:
        if not self.can_be_shorter():
            return None
        got = self.plan_level(sub)
        self.planned += 1
        self.planned_steps = max(self.planned_steps, max(tr.arrival_step for tr in got[0]))
        return got


def stacked_while_shorter(problem: SwarmProblem, extra: dict, bounded: BesideLevels) -> tuple[Stage | None, bool]:
    """The stacked plan on ``bounded.levels`` (:func:`join_levels`), its levels planned by ``bounded`` only while
    it can still be shorter than ``bounded``'s rival (round 25A), why it stopped said in ``extra["stacked"]``:
    (the stacked plan or None, whether any stacked plan could be shorter at all before a level was planned;
    False: no level was planned, so nothing depends on the level options)."""
    could = bounded.can_be_shorter()
    stacked = join_levels(problem, bounded.levels, extra, bounded) if could else None
    extra["stacked"] = bounded.stopped or extra["stacked"]
    return stacked, could


def join_levels(
    problem: SwarmProblem,
    levels: Levels | None,
    extra: dict,
    plan_level: Callable[[SwarmProblem], tuple[list[GridTrack], SwarmStage, int] | None],
) -> Stage | None:
    """Each group of types on a level of its own (``levels``, :func:`~proxplan.planner.swarm.levels.stack_levels`),
    each level planned apart by ``plan_level`` (its tracks, the stage that gave them and the vehicle
    plannings it made; :func:`_level_planner`), joined by vertical steps
    (:mod:`proxplan.planner.swarm.stacked`); None where no stack fits the box or a step or a level
    gives no plan (said in ``extra["stacked"]``)."""
    if levels is None:
        extra["stacked"] = "no stack of levels fits the free box"
        return None
    t0 = time.perf_counter()
    counts = {"planned": 0}
    stages: list[str] = []

    def plan_one_level(sub: SwarmProblem) -> list[GridTrack] | None:
        got = plan_level(sub)
        if got is None:  # not made (BesideLevels)
            return None
        tracks, stage, planned = got
        stages.append(stage)
        counts["planned"] += planned
        return tracks

    try:
        plan, what = stacked_tracks(problem, levels, plan_one_level)
    except PlanNotFound as err:
        plan, what = None, f"a level gave no plan ({err.message})"
    heights = "/".join(f"{z:.2f}" for z in levels.heights_m)
    groups = " | ".join(",".join(problem.vehicles[t].name for t in g) for g in levels.groups)
    extra["stacked"] = (
        f"levels {heights} m ({groups}): {what}; levels planned by {', '.join(stages)} in "
        f"{counts['planned']} vehicle plannings, "
        f"{time.perf_counter() - t0:.1f} s"
    )
    if plan is None:
        return None
    makespans = ", ".join(f"{m:.2f}" for m in plan.level_makespans_s)
    coordination = f"stacked levels {heights} m ({groups}), levels planned apart ({makespans} s), {what}"
    return Stage(plan.tracks, "stacked", coordination, lambda a: [plan.chains[a]])


def stacked_without_lattice(
    stacked: Stage | None, not_found: PlanNotFound | None, opts: SwarmOptions, extra: dict
) -> Stage:
    """The stacked plan where LaCAM stopped on its budget (``not_found``), saying so; where there is no
    stacked plan either, LaCAM's :class:`PlanNotFound` with the stacked plan's reason. Handed on as the
    searched stage (no lattice plan to choose from again)."""
    assert not_found is not None
    if stacked is None:
        raise PlanNotFound(
            f"{not_found.message}; stacked plan: {extra.get('stacked', 'not tried')}",
            vehicles=not_found.vehicles,
            details=not_found.details,
        )
    spent = extra.get("counts", {}).get("planned", 0)
    why = f"prioritised planning gave up ({spent} vehicle plannings); " if opts.prioritized else ""
    return replace(stacked, coordination=f"{why}LaCAM: {not_found.message}; {stacked.coordination}")
