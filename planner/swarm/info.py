"""What the swarm layer tells its caller about a plan: the stage that produced the tracks, the
bounds and what each stage did (:class:`SwarmInfo`, a typed record; ``plan.metrics["swarm"]`` is
its :meth:`SwarmInfo.to_metrics` form)."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace
from typing import TYPE_CHECKING

from proxplan.planner.swarm.stage import Stage, SwarmStage

if TYPE_CHECKING:  # types only: these modules import this one
    from proxplan.planner.swarm.levels import Levels
    from proxplan.planner.swarm.options import SwarmOptions
    from proxplan.planner.swarm.problem import SwarmProblem
    from proxplan.planner.swarm.tracks import GridTrack


@dataclass(frozen=True)
class LatticeInfo:
    """The coordination lattice and the LaCAM search on it."""

    spacing_m: float
    levels_m: list[float]
    vertices: int
    steps: int  # coordination steps (configurations - 1)
    nodes: int  # LaCAM configurations generated
    tests: int  # exact synchronous pair tests computed
    time_s: float  # wall time of the search, s (reported, never steering)


@dataclass(frozen=True)
class RetimeInfo:
    """The continuous re-timing passes."""

    passes: int
    replaced: int
    makespan_after_pass_s: list[float]
    time_s: float
    skipped: int = 0  # re-timings not run again: nothing within reach changed since they gave nothing


@dataclass(frozen=True)
class MakespanRepairInfo:
    """The neighbourhoods of the latest vehicles planned again (:mod:`proxplan.planner.swarm.makespan`)."""

    makespan_before_s: float
    makespan_after_s: float
    tried: int
    replaced: int
    plannings: int
    time_s: float
    solo: int = 0  # of ``replaced``: the latest vehicle planned again alone, the others kept
    # the repaired stacked plan failed the verifier and the tracks before the repair were kept (round 21A)
    verify_failed: bool = False
    refused: int = 0  # tracks planned again the verifier refused around them (VerifyGuard.fits; round 22A)


@dataclass(frozen=True)
class LevelHandOn:
    """One level of the stacked plan as first planned (:class:`GiveUpHandOn`)."""

    problem: SwarmProblem  # the level's problem (its vehicles on the level)
    searched: Stage  # its tracks before re-timing
    planned: int  # vehicle plannings its search made


@dataclass(frozen=True)
class GiveUpHandOn:
    """The plans made where prioritised planning gave up, before re-timing (:class:`SwarmHandOn`):
    the plan the stacked plan was weighed against (``rival``: the lattice plan, or, where the stacked plan
    was made beside a prioritised plan (fixed goals, round 24B; ``beside_prioritised``), that prioritised
    plan), and the stacked plan's stack and levels (their re-timing is inside the stacked plan, so
    re-timing again re-times each level and joins them again)."""

    rival: Stage
    stack: Levels | None  # None: no stack fits the box, no stacked plan tried, or none could be shorter (25A)
    levels: tuple[LevelHandOn, ...] | None  # bottom first; None where no stacked plan was made
    beside_prioritised: bool = False  # rival is a prioritised plan that was found, not the lattice plan


@dataclass(frozen=True)
class SwarmHandOn:
    """What a plan of the swarm layer hands on so that ``optimized`` (:mod:`proxplan.planner.refine_stage`)
    can re-time its own tracks with other options, or plan other stages on the same problem, instead
    of planning the swarm layer again (:func:`proxplan.planner.swarm.plan.swarm_again`). Not in the
    plan's metrics."""

    problem: SwarmProblem  # the problem it planned (keep-outs, and the memo of single-vehicle searches)
    options: SwarmOptions  # the options it planned with
    lower_bound_s: float  # the straight-line lower bound of the scenario, s
    assigned: bool  # the goals were assigned (Scenario.assign_goals)
    searched: Stage  # the tracks of the stage that produced them, before re-timing
    # the pass with both wavefronts' tracks before re-timing, where that pass gave other tracks (it was
    # then re-timed and compared with the plan without; swarm.heights); None where it did not
    heights: Stage | None
    extra: dict  # the stage records of the plan (SwarmInfo's fields after time_s), as planned
    # where prioritised planning gave up (or did not run), or where the stacked plan was made beside it
    give_up: GiveUpHandOn | None = None
    # the plan's final tracks by agent (after re-timing and the makespan repair; before any unfreeze
    # step, swarm.frozen): what ``optimized``'s longer makespan repair starts from (refine_stage)
    tracks: dict[int, GridTrack] | None = None


@dataclass(frozen=True)
class SwarmInfo:
    """See module. Times are s; wall times are reported, never used to steer (budgets are counts)."""

    stage: SwarmStage
    coordination: str  # one line: how the tracks were found
    vehicles: int
    lower_bound_s: float  # largest straight-line rest-to-rest time of any vehicle: no plan is shorter
    initial_makespan_s: float  # after the stage that produced the tracks
    makespan_s: float  # after re-timing and the makespan repair
    time_s: float
    kept_straight: str | None = None  # straight lines kept, vehicles planned around them, or why not
    kept_straight_time_s: float | None = None
    yielding: str | None = None  # straight lines with one vehicle of each conflicting pair yielding (swarm.yielding)
    prioritised: str | None = None  # what each order of prioritised planning gave
    prioritised_time_s: float | None = None
    # SwarmOptions.heights: what prioritised planning with both wavefronts gave and which whole plan was kept
    heights: str | None = None
    heights_time_s: float | None = None
    lattice: LatticeInfo | None = None
    stacked: str | None = None  # the stacked plan (swarm.stacked): its levels, what it gave or why not
    retiming: RetimeInfo | None = None
    # the latest vehicles planned again with those in their way (swarm.makespan): the makespan
    # after re-timing and after this, neighbourhoods tried and replaced, single-vehicle plannings
    makespan_repair: MakespanRepairInfo | None = None
    counts: dict[str, int] = field(default_factory=dict)  # search effort (vehicles planned, repairs, ...)
    # what ``optimized`` re-times or plans on again (SwarmHandOn); not in the metrics
    hand_on: SwarmHandOn | None = field(default=None, repr=False, compare=False)

    def to_metrics(self) -> dict:
        """The plan.json form (``metrics.swarm``), without the hand-on."""
        out = asdict(replace(self, hand_on=None))
        del out["hand_on"]
        return out
