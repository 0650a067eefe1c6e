"""What the stages of one swarm plan give (:class:`Planned`, :func:`proxplan.planner.swarm.stages.plan_stages`):
the tracks kept and the records handed on."""

from __future__ import annotations

from dataclasses import dataclass

from proxplan.planner.swarm.info import GiveUpHandOn, MakespanRepairInfo, RetimeInfo
from proxplan.planner.swarm.stage import Stage
from proxplan.planner.swarm.tracks import GridTrack

__all__ = ["Planned"]


@dataclass
class Planned:
    """What the stages of :func:`~proxplan.planner.swarm.stages.plan_stages` give: the stage whose tracks were kept, the final tracks by agent,
    the makespan before re-timing (s), what re-timing and the makespan repair did, the other stages'
    records (``SwarmInfo``'s extra fields), and what :class:`SwarmHandOn` hands on: the searched stage's
    tracks before re-timing, the pass with both wavefronts' (where it gave other tracks) and the
    give-up plans (where prioritised planning gave up)."""

    stage: Stage
    tracks: dict[int, GridTrack]
    initial_makespan_s: float
    retiming: RetimeInfo
    repair: MakespanRepairInfo | None
    extra: dict
    searched: Stage
    heights: Stage | None
    give_up: GiveUpHandOn | None = None
