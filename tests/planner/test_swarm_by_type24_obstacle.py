"""Interchangeable vehicles whose straight lines pass through an obstacle (issue 37 item 5, round 24S):
each such line is flown round the obstacle through a corner beside its blocked stretch
(``yielding.around_obstacle``), and the passing stage times those vehicles late instead of giving up; the
plan is conflict-free, statically free, passes the verifier and is the same on every run."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.passes import passing_stage
from proxplan.planner.swarm.prioritised_stage import horizon_steps
from proxplan.planner.swarm.straight import straight_step_conflicts
from proxplan.planner.swarm.yielding import AROUND_STEPS, around_obstacle
from proxplan.planner.timing import assemble_plan
from proxplan.verify import verify_plan

from .test_swarm_by_type_passes import _assigned


@pytest.fixture(scope="module")
def pillar12():
    return _assigned("pillar", 12)


def _through(problem) -> list[int]:
    return [i for i, j in straight_step_conflicts(problem) if i == j]


def test_a_line_through_the_obstacle_gets_a_free_corner_on_each_side(pillar12):
    """pillar-12 by type has lines through the pillar (4 when written); each gets one chain per side,
    start -> corner -> goal, both legs statically free, the corners on opposite sides of its line and
    within the search; a free line gets none."""
    _, _, problem = pillar12
    through = _through(problem)
    assert through
    for a in through:
        s, g = problem.starts_m[a], problem.goals_m[a]
        chains = around_obstacle(problem, a)
        assert len(chains) == 2
        sides = []
        for chain in chains:
            assert np.allclose(chain[0], s) and np.allclose(chain[-1], g)
            assert problem.segment_free(chain[0], chain[1]) and problem.segment_free(chain[1], chain[2])
            d = g - s
            sides.append(np.sign(d[0] * (chain[1][1] - s[1]) - d[1] * (chain[1][0] - s[0])))
            # the corner lies beside the line, within the search's widest offset
            aside = np.linalg.norm(np.cross(chain[1] - s, d)) / np.linalg.norm(d)
            assert aside <= AROUND_STEPS * 0.5 * problem.reach_xy_m + 1e-9
        assert sorted(sides) == [-1.0, 1.0]
    free = next(a for a in range(problem.n_agents) if a not in through)
    assert around_obstacle(problem, free) == []


def test_the_passing_stage_flies_lines_through_an_obstacle_round_it(pillar12):
    """Where a straight line leaves the static free space the passing stage no longer gives up: it
    gives a plan in which those vehicles fly round the obstacle, no two tracks conflict (the swarm
    layer's exact test), every flown sample is statically free, the verifier passes it, within 1.5 B
    (1.22 B when written), and the same plan comes on a second run."""
    scenario, bound, problem = pillar12
    pairs = straight_step_conflicts(problem)
    got = passing_stage(problem, horizon_steps(bound), pairs)
    assert got.stage is not None, got.note
    tracks = got.stage.tracks
    for a in _through(problem):
        assert a in got.yielders
        assert tracks[a].route_m is not None and len(tracks[a].route_m) > 2  # not its straight line
    occ = Occupancy(problem, tracks, max(tr.arrival_step for tr in tracks) + 40)
    assert all(not occ.conflicting_agents(tr) for tr in tracks)
    for tr in tracks:
        q = tr.position_at_steps(np.arange(tr.arrival_step + 1))
        assert problem.static_free(q).all()
    makespan = max(tr.arrival_s for tr in tracks)
    assert makespan < 1.5 * bound
    timed = {problem.names[tr.agent]: tr.timed_path() for tr in tracks}
    assert verify_plan(assemble_plan(scenario, timed, method="swarm", notes=[]), scenario) == []
    again = passing_stage(problem, horizon_steps(bound), pairs)
    assert again.stage is not None
    for a, b in zip(tracks, again.stage.tracks):
        assert np.array_equal(
            a.position_at_steps(np.arange(a.arrival_step + 1)), b.position_at_steps(np.arange(b.arrival_step + 1))
        )
