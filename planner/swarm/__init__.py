"""Swarm planning on a shared roadmap (``--method roadmap``, and formation changes of
``ROADMAP_MIN_VEHICLES`` or more): a lattice roadmap with precomputed conflict sets between its
atoms, a single-vehicle space-time A* on it and a multi-agent layer (priority-based search or
prioritised planning), timed with Ruckig into the same timed paths as the sampling planner.

Modules: :mod:`~proxplan.planner.swarm.keepout` (per-pair keep-outs from the cut-off tables),
:mod:`~proxplan.planner.swarm.roadmap` (lattice, atoms, conflict sets),
:mod:`~proxplan.planner.swarm.runs` (agents, moves, paths, run occupancy),
:mod:`~proxplan.planner.swarm.search` (single-vehicle space-time A*),
:mod:`~proxplan.planner.swarm.pbs` (PBS and PP), :mod:`~proxplan.planner.swarm.plan` (scenario ->
roadmap -> search -> timed paths).
"""

from proxplan.planner.swarm.pbs import SearchResult, pbs, prioritized
from proxplan.planner.swarm.plan import (
    ROADMAP_MIN_VEHICLES,
    SEARCHES,
    RoadmapOptions,
    roadmap_applicable,
    roadmap_timed,
    search_plan,
)
from proxplan.planner.swarm.roadmap import Roadmap, build_roadmap
from proxplan.planner.swarm.runs import Agent, Path
from proxplan.planner.swarm.search import Search

__all__ = [
    "ROADMAP_MIN_VEHICLES",
    "SEARCHES",
    "Agent",
    "Path",
    "Roadmap",
    "RoadmapOptions",
    "Search",
    "SearchResult",
    "build_roadmap",
    "pbs",
    "prioritized",
    "roadmap_applicable",
    "roadmap_timed",
    "search_plan",
]
