"""What a prioritised pass (:mod:`proxplan.planner.swarm.priority`) is asked and hands back: its knobs
(:class:`PriorityOptions`; budgets are counts), its result (:class:`PriorityResult`) and its giving up
(:class:`PrioritizedFailed`, pickled back from a Dask worker with its fields).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from proxplan.planner.swarm.tracks import GridTrack

__all__ = ["PrioritizedFailed", "PriorityOptions", "PriorityResult"]


@dataclass(frozen=True)
class PriorityOptions:
    """Knobs of prioritised planning; budgets are counts."""

    max_repairs: int  # repairs (a failed vehicle planned first, those in conflict with it again) per pass
    max_plannings: int | None = None  # single-vehicle plannings of the pass (repairs' included); None: no cap
    hold_s: float = 0.0  # a vehicle not planned yet is assumed to hold its start this long, then leave, s
    through: bool = True  # fly through waypoints without stopping (else rest to rest at each)
    # a vehicle that cannot be planned within the repairs flies its ideal track in collision, and the
    # collisions are removed at the end (swarm.lns) within the pass's plannings (False: give the pass up)
    collisions: bool = True
    # of the collision repair's draws; the swarm layer leaves it at 0 (its prioritised plans do not
    # depend on the plan's seed: the verification policy re-plans with another seed only other plans)
    seed: int = 0
    # a vehicle not planned yet holds its start (its keep-out occupied) until it is planned, instead of
    # being predicted to leave; a vehicle that cannot be planned then releases only the starts in the
    # way of its ideal track (those vehicles predicted to leave, and planned next: see module)
    reserve_starts: bool = False
    # every vehicle planned with both wavefronts, the earlier arrival kept (plan_one's ``heights``)
    heights: bool = False
    # give the pass up as soon as what is left of ``max_plannings`` cannot plan the vehicles still
    # queued (each needs one planning at least): it would give up on the budget all the same, later
    # (the caller then charges the whole budget: ``PrioritizedFailed.charged``)
    give_up_early: bool = False
    # give the pass up once more vehicles than this fly in collision (None: no cap; prioritised_stage
    # passes in_collision_cap): charged what it would be at least if it went on with no more of them,
    # one planning per vehicle queued, and the collision repair's whole count (what a repair that does
    # not converge is charged), so the passes after it see about the budget they saw before
    max_in_collision: int | None = None
    # a vehicle about to fly in collision (repairs spent, or going round in a circle) is planned once more
    # through a holding point beside its line (swarm.holding). Off: at 128 on pillar and corridor it did not
    # make a pass complete, and it costs CPU (docs/planner.md, stop 59 round 21B)
    holding: bool = False
    # every vehicle also along its route raised over the others (swarm.raised), the earlier arrival kept
    raised: bool = False


@dataclass
class PriorityResult:
    tracks: dict[int, GridTrack]
    planned: int  # vehicle plannings done (repairs plan some again)
    repairs: int
    history: list[str] = field(default_factory=list)  # what each repair was for
    against_order: int = 0  # repairs that reversed an order set by an earlier repair
    collision_repairs: int = 0  # neighbourhoods planned again by the collision repair (swarm.lns)
    released: int = 0  # reserved starts released for a vehicle in their way (reserve_starts)
    held: int = 0  # vehicles planned through a holding point (PriorityOptions.holding)


class PrioritizedFailed(Exception):
    """A pass gave up; ``planned``: the single-vehicle plannings it made; ``charged``: those its
    budget is charged (``planned``, or the whole ``max_plannings`` when it gave up early because
    they could not suffice: ``PriorityOptions.give_up_early``)."""

    def __init__(self, agent: int, repairs: int, history: list[str], *, planned: int = 0, charged: int | None = None):
        super().__init__(f"agent {agent} could not be planned after {repairs} repairs")
        self.agent, self.repairs, self.history, self.planned = agent, repairs, history, planned
        self.charged = planned if charged is None else charged

    def __reduce__(self):  # pickled back from a Dask worker with its fields (the default passes args only)
        return _failed, (self.agent, self.repairs, self.history, self.planned, self.charged)


def _failed(agent: int, repairs: int, history: list[str], planned: int, charged: int) -> PrioritizedFailed:
    return PrioritizedFailed(agent, repairs, history, planned=planned, charged=charged)
