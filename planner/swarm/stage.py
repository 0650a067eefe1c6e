"""What one stage of the swarm layer hands to the next (:class:`Stage`): every vehicle's track and
the waypoint chains that re-timing (:mod:`proxplan.planner.swarm.retime`) moves it along."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np

from proxplan.planner.swarm.problem import SwarmProblem
from proxplan.planner.swarm.tracks import GridTrack

__all__ = ["Stage", "SwarmStage", "own_routes"]

# straight: one synchronised straight step (CAPT's case); prioritised: prioritised continuous
# planning; lattice: the lattice coordination flown in lock-step (prioritised planning gave up);
# stacked: each group of types on a level of its own, planned apart (prioritised planning gave up)
SwarmStage = Literal["straight", "prioritised", "lattice", "stacked"]


@dataclass
class Stage:
    """Tracks of every agent (by agent index) from one stage, and what the stage reports."""

    tracks: list[GridTrack]
    stage: SwarmStage
    coordination: str
    routes: Callable[[int], list[np.ndarray]]  # the stage's own waypoint chain of an agent (re-timing)
    # prioritised planning's pass that gave the tracks: (order label, hold s); None for the other stages
    pass_key: tuple[str, float] | None = None


def own_routes(problem: SwarmProblem, tracks: list[GridTrack]) -> Callable[[int], list[np.ndarray]]:
    """The straight line and the route each vehicle's track was timed along (re-timing)."""
    routes = {tr.agent: tr.route_m for tr in tracks}

    def chains(a: int) -> list[np.ndarray]:
        out = [np.array([problem.starts_m[a], problem.goals_m[a]])]
        r = routes.get(a)
        if r is not None and len(r) > 2:
            out.append(r)
        return out

    return chains
