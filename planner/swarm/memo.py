"""Single-vehicle searches remembered by what they were searched against.

The exact timing along a chain (:func:`proxplan.planner.swarm.chain.time_chain`) and the wavefront
route (:func:`proxplan.planner.swarm.wave.wave_route`) are functions of the vehicle, their own
arguments and the *content* of the :class:`~proxplan.planner.swarm.occupancy.Occupancy` they ask
(its horizon and the set of other tracks: every query of the occupancy is a union over those
tracks, so it does not depend on the order they were put in). Prioritised planning asks the same
searches against the same tracks again and again: every pass of every order starts from the same
occupancy (with reserved starts, every start held), a vehicle's ideal track is timed against the
empty occupancy at each failure, and two orders whose repairs and releases bring the passes to the
same state plan the same vehicles against the same tracks. So each search's answer is kept under
a key of its arguments and :meth:`Occupancy.content_key` (a digest of every track's samples), and
asked again it is given back, not searched again: the same answer, so the same plans, at the cost
of a digest per change of the occupancy. :class:`Memo` lives on the
:class:`~proxplan.planner.swarm.problem.SwarmProblem` (one per problem: its keep-outs, limits and
static free space are part of every answer).
"""

from __future__ import annotations

from collections.abc import Callable, Hashable
from typing import TypeVar

# answers kept, at most (the oldest dropped first; the bound only changes the speed, never an answer):
# a stage of prioritised planning makes at most 6 plannings per vehicle (SwarmOptions.plannings_per_vehicle)
# of at most 4 searches each (plan_one: straight chain, route, its timing, the slow route's timing), so
# 256 vehicles ask about 6 x 4 x 256 = 6144 answers; each holds one track (a few hundred grid samples,
# 10-20 kB), so 8192 answers stay below about 160 MB
MAX_ENTRIES = 8192
# answers about the static free space kept, at most (SwarmProblem.static_memo): a wavefront grid of the
# whole free box (at most about 12 m x 12 m of 7.5 cm cells: 26 kB of booleans) per route box and height,
# and a bool per segment checked (about 60 per planning on corridor-32, of which most recur); 65536
# answers of either kind stay below about 100 MB even if all were grids of separate boxes
MAX_STATIC_ENTRIES = 65536

T = TypeVar("T")


class Memo:
    """Answers of deterministic searches by key (see module); counts hits and misses."""

    def __init__(self, max_entries: int = MAX_ENTRIES):
        self.max_entries = max_entries
        self._answers: dict[Hashable, object] = {}
        self.hits = 0
        self.misses = 0

    def __len__(self) -> int:
        return len(self._answers)

    def get(self, key: Hashable, compute: Callable[[], T]) -> T:
        """The answer kept under ``key``, else ``compute()`` (kept)."""
        if key in self._answers:
            self.hits += 1
            return self._answers[key]  # type: ignore[return-value]
        self.misses += 1
        out = compute()
        if self.max_entries <= 0:  # keeps nothing (to measure or test without it)
            return out
        if len(self._answers) >= self.max_entries:
            del self._answers[next(iter(self._answers))]
        self._answers[key] = out
        return out

    def __getstate__(self) -> dict:  # sent to a Dask worker empty: answers are only worth keeping here
        return {"max_entries": self.max_entries, "_answers": {}, "hits": 0, "misses": 0}


__all__ = ["MAX_ENTRIES", "MAX_STATIC_ENTRIES", "Memo"]
