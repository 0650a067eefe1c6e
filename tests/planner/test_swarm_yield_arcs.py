"""Smooth detours for yielding vehicles (issue 37 item 5, round 21S): the arc move
(proxplan.planner.timing.arcs) stays within the vehicle's limits and is consistent; its timing against
others' tracks (proxplan.planner.swarm.arc_timing) is conflict-free; the yielding stage with arcs gives
a shorter verified plan than with corners alone; the swarm layer keeps the shorter plan once re-timed."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.physics import KinematicLimits
from proxplan.planfile import scenario_from_dict
from proxplan.planner.formations import layout_doc
from proxplan.planner.swarm import SwarmOptions, swarm_timed
from proxplan.planner.swarm.arc_timing import time_arc
from proxplan.planner.swarm.goals import apply_assignment
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.prioritised_stage import horizon_steps
from proxplan.planner.swarm.problem import swarm_problem
from proxplan.planner.swarm.straight import own_straight_track, straight_step_conflicts
from proxplan.planner.swarm.tracks import GRID_DT_S
from proxplan.planner.swarm.yielding import yielding_stage
from proxplan.planner.timing import assemble_plan
from proxplan.planner.timing.arcs import ArcMove
from proxplan.planner.timing.profile import rest_to_rest
from proxplan.verify import verify_plan

LIMITS = KinematicLimits(2.0, 4.0, 16.0)  # the built-in types' limits in the bench layouts


@pytest.fixture(scope="module")
def circle16():
    scenario, record = apply_assignment(scenario_from_dict(layout_doc("circle", 16, assign="by_type"), label="test"))
    return scenario, float(record["lower_bound_s"]), swarm_problem(scenario)


def _sampled(move: ArcMove, n: int = 3000):
    t = np.linspace(0.0, move.duration, n + 1)
    p, v, a = (np.array(x) for x in zip(*(move.at_time(float(x)) for x in t)))
    return t, p, v, a


@pytest.mark.parametrize("bulge", [0.1, 0.25, 0.5])
def test_an_arc_stays_within_the_limits_and_its_states_agree(bulge):
    """A 1.2 m arc bulging sideways: speed and acceleration norms within the limits at 3000 instants,
    the jerk of the sampled accelerations within them too (finite differences); positions, velocities
    and accelerations integrate into each other; it starts and ends at rest at its ends, passes the
    bulge's point at half time (the profile is symmetric) and its grid samples are its own positions."""
    p0, p1 = np.array([0.0, 0.0, 1.5]), np.array([1.2, 0.0, 1.5])
    w = np.array([0.0, bulge, 0.0])
    move = ArcMove(p0, p1, w, LIMITS, GRID_DT_S)
    t, p, v, a = _sampled(move)
    h = np.diff(t)[:, None]
    assert np.linalg.norm(v, axis=1).max() <= LIMITS.max_speed_mps
    assert np.linalg.norm(a, axis=1).max() <= LIMITS.max_accel_mps2
    assert (np.linalg.norm(np.diff(a, axis=0), axis=1) / h[:, 0]).max() <= LIMITS.max_jerk_mps3
    assert np.abs(p[1:] - p[:-1] - h * (v[1:] + v[:-1]) / 2).max() < 1e-5
    assert np.abs(v[1:] - v[:-1] - h * (a[1:] + a[:-1]) / 2).max() < 1e-4
    assert np.allclose(p[0], p0) and np.allclose(p[-1], p1) and np.allclose(move.end_m, p1)
    assert np.allclose(v[0], 0.0) and np.allclose(v[-1], 0.0)
    assert np.allclose(move.at_time(0.5 * move.duration)[0], 0.5 * (p0 + p1) + w, atol=1e-9)
    grid = move.positions()
    assert grid.shape == (move.steps + 1, 3)
    for k in (0, move.steps // 3, move.steps // 2, move.steps):
        assert np.allclose(grid[k], move.at_time(k * GRID_DT_S)[0], atol=1e-9)


def test_an_arc_without_bulge_is_the_straight_line_and_a_wider_bulge_takes_longer():
    """No bulge: the straight rest-to-rest move's steps; the duration grows with the bulge."""
    p0, p1 = np.array([0.0, 0.0, 1.0]), np.array([0.0, 1.2, 1.0])
    steps = [ArcMove(p0, p1, np.array([b, 0.0, 0.0]), LIMITS, GRID_DT_S).steps for b in (0.0, 0.1, 0.2, 0.3)]
    assert steps[0] == rest_to_rest(1.2, LIMITS, GRID_DT_S).steps
    assert steps == sorted(steps) and steps[-1] > steps[0]


def test_an_arc_is_timed_clear_of_the_others_tracks(circle16):
    """A vehicle of a conflicting pair timed along an arc against its partner's straight line: the
    track conflicts with no track in the occupancy, leaves no earlier than the others allow and
    flies one arc; asked to arrive before the arc alone could, there is none."""
    _, bound, problem = circle16
    i, j = next((i, j) for i, j in straight_step_conflicts(problem) if i != j)
    occ = Occupancy(problem, [own_straight_track(problem, j)], horizon_steps(bound))
    side = np.array([0.0, 0.0, 1.0])
    d = problem.goals_m[i] - problem.starts_m[i]
    w = np.cross(side, d)
    w = 0.5 * problem.reach_xy_m * w / np.linalg.norm(w)
    got = next(
        (r for r in (time_arc(occ, i, s * f * w) for f in (1.0, 1.5, 2.0) for s in (1.0, -1.0)) if r is not None),
        None,
    )
    assert got is not None
    assert not occ.conflicting_agents(got.track)
    assert len(got.track.moves) == 1 and isinstance(got.track.moves[0][1], ArcMove)
    move = got.track.moves[0][1]
    assert got.arrival_step == got.track.moves[0][0] + move.steps == got.track.arrival_step
    assert time_arc(occ, i, move.bulge, arrive_by=move.steps - 1) is None


def test_arcs_shorten_the_yielding_plan_and_it_verifies(circle16):
    """circle-16 by type, keeping right: with arcs the plan is shorter than with corners alone (1.36 B
    against 1.49 B when written), no two tracks conflict, and the plan passes the verifier."""
    scenario, bound, problem = circle16
    pairs = straight_step_conflicts(problem)
    corners = yielding_stage(problem, horizon_steps(bound), right_hand=True, pairs=pairs, arc_factors=())
    arcs = yielding_stage(problem, horizon_steps(bound), right_hand=True, pairs=pairs)
    assert corners.stage is not None and arcs.stage is not None
    tracks = arcs.stage.tracks
    assert max(tr.arrival_s for tr in tracks) < max(tr.arrival_s for tr in corners.stage.tracks) - 0.05 * bound
    assert any(isinstance(mv, ArcMove) for tr in tracks for _, mv in tr.moves)
    occ = Occupancy(problem, tracks, max(tr.arrival_step for tr in tracks) + 40)
    assert all(not occ.conflicting_agents(tr) for tr in tracks)
    timed = {problem.names[tr.agent]: tr.timed_path() for tr in tracks}
    assert verify_plan(assemble_plan(scenario, timed, method="swarm", notes=[]), scenario) == []


def test_the_swarm_layer_plan_is_no_longer_than_the_yielding_plan_and_repeats(circle16):
    """By type, the plan kept (the shorter of the yielding and the prioritised plans once re-timed, then
    repaired) is never longer than the yielding plan alone; the same problem gives the same plan."""
    scenario, bound, problem = circle16
    opts = SwarmOptions(workers=1, reserve_starts=False)
    paths, info = swarm_timed(scenario, opts)
    alone = [
        yielding_stage(problem, horizon_steps(bound), right_hand=r, pairs=straight_step_conflicts(problem)).stage
        for r in (False, True)
    ]
    best = min(max(tr.arrival_s for tr in s.tracks) for s in alone if s is not None)
    assert info.makespan_s <= best + 1e-9
    again, info2 = swarm_timed(scenario, opts)
    assert info2.makespan_s == info.makespan_s
    for name, path in paths.items():
        assert np.array_equal(path.knot_t_s, again[name].knot_t_s)
        assert np.allclose(path.knot_p_m, again[name].knot_p_m)
