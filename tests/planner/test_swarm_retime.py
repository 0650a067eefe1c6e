"""Continuous re-timing (proxplan.planner.swarm.retime): a vehicle whose re-timing gave nothing is
not re-timed again until a track within reach of its chains changes; the plan is the same as
re-timing every vehicle in every pass."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.planfile import scenario_from_dict
from proxplan.planner.formations import grid_reshuffle
from proxplan.planner.swarm import Lacam, SyncTable, build_lattice, swarm_problem
from proxplan.planner.swarm.lockstep import lockstep_tracks
from proxplan.planner.swarm.occupancy import Occupancy, track_digest
from proxplan.planner.swarm.retime import improve, route_chain
from proxplan.planner.swarm.tracks import GRID_DT_S


def _retimed(skip: bool, through: bool) -> tuple[list[bytes], dict]:
    problem = swarm_problem(scenario_from_dict(grid_reshuffle(16), label="test scenario"))  # its own memo
    lat = build_lattice(problem)
    configurations = (
        Lacam(lat, SyncTable(problem.keepouts, problem.type_index, lat.pos_mm)).solve(max_nodes=2000).configurations
    )
    tracks = lockstep_tracks(lat, configurations)
    by_agent = {tr.agent: tr for tr in tracks}
    occ = Occupancy(problem, tracks, int(round((max(tr.arrival_s for tr in tracks) + 5.0) / GRID_DT_S)))

    def chains(a: int) -> list[np.ndarray]:
        return [np.array([problem.starts_m[a], problem.goals_m[a]]), route_chain(lat, configurations, a)]

    counts = improve(occ, by_agent, chains, passes=3, through=through, skip_unchanged=skip)
    return [track_digest(by_agent[a]) for a in sorted(by_agent)], counts


@pytest.mark.parametrize("through", [False, True])
def test_skipping_unchanged_vehicles_gives_the_same_plan(through):
    """grid-16's lattice plan re-timed in three passes (rest to rest at waypoints, and through them):
    with the skip some re-timings are not run again (8 rest to rest when written), every track is
    the same as without, and so are the counts."""
    skipped, with_skip = _retimed(True, through)
    every, without = _retimed(False, through)
    assert skipped == every
    assert without["skipped"] == 0 and with_skip["skipped"] > 0
    assert with_skip["passes"] == without["passes"] >= 2
    assert with_skip["replaced"] == without["replaced"] > 0
    assert with_skip["makespan_after_pass_s"] == without["makespan_after_pass_s"]
