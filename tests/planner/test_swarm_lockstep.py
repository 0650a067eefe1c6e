"""The coordination plan flown in dependency order (proxplan.planner.swarm.lockstep): each group of
moves starts when the moves within its reach of earlier steps have ended, never later than lock-step
and conflict-free like it."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.planfile import scenario_from_dict
from proxplan.planner.formations import grid_reshuffle
from proxplan.planner.swarm import Lacam, SyncTable, build_lattice, swarm_problem
from proxplan.planner.swarm.lns import colliding_pairs
from proxplan.planner.swarm.lockstep import lockstep_tracks, segment_distance_xy_m
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.timing import assemble_plan
from proxplan.verify import verify_plan


def _verified(sc, problem, tracks) -> list:
    timed = {problem.names[t.agent]: t.timed_path() for t in tracks}
    return verify_plan(assemble_plan(sc, timed, method="swarm", notes=[]), sc)


def test_segment_distance_equals_dense_sampling():
    """The horizontal distance between two segments equals the least distance between dense samples
    of both (within the sampling's resolution), and is zero where they cross."""
    rng = np.random.default_rng(4)
    s = np.linspace(0.0, 1.0, 401)
    for _ in range(60):
        p0, p1, q0, q1 = rng.uniform(-1.0, 1.0, (4, 3))
        got = float(segment_distance_xy_m(p0, p1, q0, q1))
        P = p0[None, :2] + s[:, None] * (p1 - p0)[None, :2]
        Q = q0[None, :2] + s[:, None] * (q1 - q0)[None, :2]
        brute = float(np.min(np.linalg.norm(P[:, None] - Q[None], axis=2)))
        assert got <= brute + 1e-12
        # each closest point lies within half a sample spacing (segments at most 2 sqrt(2) m long,
        # 400 spacings: 7.1 mm) of a sample, on both segments
        assert brute - got <= 2.0 * 0.5 * 2.0 * np.sqrt(2.0) / 400
    assert (
        float(segment_distance_xy_m(np.array([-1.0, 0]), np.array([1.0, 0]), np.array([0, -1.0]), np.array([0, 1.0])))
        == 0.0
    )


def test_far_apart_vehicles_do_not_wait_for_each_others_steps():
    """Two vehicles 4.5 m apart (beyond any keep-out's reach), each flying one long and one short move
    in opposite steps: lock-step flies two long steps one after the other, dependency order lets each
    fly its own two moves back to back, so the plan ends a long move's time minus a short move's
    earlier. Both pass the verifier."""
    doc = grid_reshuffle(2, seed=0)
    doc["workspace"] = {"min": [-5.0, -2.0, 0.0], "max": [5.0, 2.0, 3.0]}
    doc["vehicles"]["v000"].update(start=[-3.6, 0.0, 1.5], goal=[-1.8, 0.0, 1.5])
    doc["vehicles"]["v001"].update(start=[0.6, 0.0, 1.5], goal=[2.4, 0.0, 1.5])
    sc = scenario_from_dict(doc, label="test scenario")
    problem = swarm_problem(sc)
    lat = build_lattice(problem)
    s0, g0, s1, g1 = (int(x) for x in (lat.start_v[0], lat.goal_v[0], lat.start_v[1], lat.goal_v[1]))

    def vertex_at(x: float) -> int:
        return int(np.argmin(np.linalg.norm(lat.pos_m - [x, 0.0, 1.5], axis=1)))

    mid0, mid1 = vertex_at(-2.1), vertex_at(0.9)  # v000: long then short; v001: short then long
    configurations = [(s0, s1), (mid0, mid1), (g0, g1)]
    lock = lockstep_tracks(lat, configurations, dependencies=False)
    dep = lockstep_tracks(lat, configurations)
    lock_end = max(t.arrival_step for t in lock)
    dep_end = max(t.arrival_step for t in dep)
    assert lock[0].moves[1][0] == lock[1].moves[1][0]  # lock-step: the second step starts for both at once
    for tr in dep:  # dependency order: each vehicle's second move follows its first at once
        assert tr.moves[1][0] == tr.moves[0][1].steps
    long_steps, short_steps = lock[0].moves[0][1].steps, dep[1].moves[0][1].steps
    assert short_steps < long_steps
    assert lock_end == 2 * long_steps
    assert dep_end == long_steps + short_steps
    assert _verified(sc, problem, lock) == [] and _verified(sc, problem, dep) == []


@pytest.mark.parametrize("seed", [0, 3])
def test_a_lattice_plan_in_dependency_order_is_never_later_and_conflict_free(seed):
    """A LaCAM plan of grid-16: flown in dependency order every vehicle arrives no later than in
    lock-step, no pair collides (the occupancy's own test), the verifier passes it, and the same
    plan gives the same tracks."""
    sc = scenario_from_dict(grid_reshuffle(16, seed=seed), label="test scenario")
    problem = swarm_problem(sc)
    lat = build_lattice(problem)
    result = Lacam(lat, SyncTable(problem.keepouts, problem.type_index, lat.pos_mm)).solve(max_nodes=2000)
    lock = lockstep_tracks(lat, result.configurations, dependencies=False)
    dep = lockstep_tracks(lat, result.configurations)
    assert all(d.arrival_step <= s.arrival_step for d, s in zip(dep, lock))
    horizon = max(t.arrival_step for t in lock) + 10
    assert colliding_pairs(Occupancy(problem, dep, horizon), range(problem.n_agents)) == set()
    assert _verified(sc, problem, dep) == []
    again = lockstep_tracks(lat, result.configurations)
    for a, b in zip(dep, again):
        np.testing.assert_array_equal(a.positions_m, b.positions_m)
