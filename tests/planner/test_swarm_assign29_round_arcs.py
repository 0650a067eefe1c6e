"""Round 29S: a straight line through an obstacle is also flown round it on the smallest statically free
arc (``yielding.round_arc_bulges``), which on corridor-64 by type is far faster alone than its corner chains."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.planfile import scenario_from_dict
from proxplan.planner.formations import layout_doc
from proxplan.planner.swarm import yielding
from proxplan.planner.swarm.arc_timing import time_arc
from proxplan.planner.swarm.chain import time_chain
from proxplan.planner.swarm.goals import apply_assignment
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.problem import swarm_problem
from proxplan.planner.swarm.tracks import GRID_DT_S
from proxplan.planner.timing.arcs import ArcMove


@pytest.fixture(scope="module")
def corridor64():
    scenario, record = apply_assignment(scenario_from_dict(layout_doc("corridor", 64, assign="by_type")))
    return swarm_problem(scenario), float(record["lower_bound_s"])


def _through(problem) -> list[int]:
    return [a for a in range(problem.n_agents) if not problem.segment_free(problem.starts_m[a], problem.goals_m[a])]


def test_free_lines_have_no_round_arcs(corridor64) -> None:
    problem, _ = corridor64
    through = set(_through(problem))
    free = [a for a in range(problem.n_agents) if a not in through][:5]
    assert free and all(yielding.round_arc_bulges(problem, a) == [] for a in free)


def test_round_arcs_are_statically_free_and_smallest(corridor64) -> None:
    problem, _ = corridor64
    through = _through(problem)
    assert through  # the two vehicles the type counts send across the wall
    step = yielding.AROUND_STEP_REACH * problem.reach_xy_m
    for a in through:
        bulges = yielding.round_arc_bulges(problem, a)
        assert bulges
        for bulge in bulges:
            k = float(np.linalg.norm(bulge)) / step
            assert abs(k - round(k)) < 1e-9 and 1 <= round(k) <= yielding.AROUND_STEPS
            move = ArcMove(problem.starts_m[a], problem.goals_m[a], bulge, problem.limits[a], GRID_DT_S)
            assert problem.static_free(move.positions()).all()
            if round(k) > 1:  # one step less on that side is not free
                smaller = bulge * (round(k) - 1) / round(k)
                sigma = np.linspace(0.0, 1.0, 400)[:, None]
                s, g = problem.starts_m[a], problem.goals_m[a]
                curve = s + sigma * (g - s) + 4.0 * sigma * (1.0 - sigma) * smaller
                assert not problem.static_free(curve).all()


def test_round_arc_alone_beats_the_corner_chains(corridor64) -> None:
    """The line setting B (v001, through the wall): alone, its arc 1.19 B, its corner chains 1.57 B."""
    problem, bound_s = corridor64
    a = problem.names.index("v001")
    occ = Occupancy(problem, [], int(4 * bound_s / GRID_DT_S))
    arcs = [time_arc(occ, a, b) for b in yielding.round_arc_bulges(problem, a)]
    chains = [time_chain(occ, a, c, through=True) for c in yielding.around_obstacle(problem, a)]
    best_arc = min(r.track.arrival_s for r in arcs if r is not None)
    best_chain = min(r.track.arrival_s for r in chains if r is not None)
    assert best_arc < 1.3 * bound_s < best_chain
