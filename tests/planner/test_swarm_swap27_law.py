"""The swap manoeuvre timed by a near time-optimal law along its path (proxplan.planner.timing.path_law,
issue 37 items 1 and 5, round 27S), and joint moves staggered where their members conflict leaving
together (proxplan.planner.swarm.pass_moves.fitted)."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.physics import KinematicLimits
from proxplan.planner.swarm.pass_moves import conflict_free, fitted, joint_moves
from proxplan.planner.swarm.tracks import GRID_DT_S
from proxplan.planner.timing.arcs import ArcMove
from proxplan.planner.timing.path_law import _cached_law, _shape_law, quadratic_law, speed_accel_floor_s
from proxplan.planner.timing.profile import rest_to_rest

from .test_swarm_by_type_passes import _assigned

LIMITS = KinematicLimits(max_speed_mps=2.0, max_accel_mps2=4.0, max_jerk_mps3=16.0)  # the bench's vehicles
REACH_M = 0.401087  # grid-64 by type's widest keep-out reach aside (problem.reach_xy_m), m


def _sampled(move: ArcMove, n: int = 4000):
    t = np.linspace(0.0, move.duration, n + 1)
    p, v, a = (np.array(x) for x in zip(*(move.at_time(float(x)) for x in t)))
    return t, p, v, a


@pytest.mark.parametrize("along", [0.0, 0.1])
@pytest.mark.parametrize("factor", [0.5, 1.0])
def test_the_law_stays_within_the_limits_and_its_states_agree(factor, along):
    """A 0.6 m swap bulging sideways (and partly along the chord): speed and acceleration norms within
    the limits at 4000 instants, the finite-difference jerk of the sampled accelerations within the jerk
    limit; positions, velocities and accelerations integrate into each other; at rest at both ends; the
    bulge's point passed at half time; the grid samples are its positions."""
    p0, p1 = np.array([0.0, 0.0, 1.5]), np.array([0.6, 0.0, 1.5])
    w = np.array([along, factor * REACH_M, 0.0])
    move = ArcMove(p0, p1, w, LIMITS, GRID_DT_S)
    t, p, v, a = _sampled(move)
    h = np.diff(t)[:, None]
    assert np.linalg.norm(v, axis=1).max() <= LIMITS.max_speed_mps
    assert np.linalg.norm(a, axis=1).max() <= LIMITS.max_accel_mps2
    assert (np.linalg.norm(np.diff(a, axis=0), axis=1) / h[:, 0]).max() <= LIMITS.max_jerk_mps3
    assert np.abs(p[1:] - p[:-1] - h * (v[1:] + v[:-1]) / 2).max() < 1e-5
    assert np.abs(v[1:] - v[:-1] - h * (a[1:] + a[:-1]) / 2).max() < 1e-4
    assert np.allclose(p[0], p0) and np.allclose(p[-1], p1)
    assert np.allclose(v[0], 0.0) and np.allclose(v[-1], 0.0) and np.allclose(a[-1], 0.0)
    assert np.allclose(move.at_time(0.5 * move.duration)[0], 0.5 * (p0 + p1) + w, atol=1e-9)
    grid = move.positions()
    assert grid.shape == (move.steps + 1, 3)
    for k in range(0, move.steps + 1, 7):
        assert np.allclose(grid[k], move.at_time(k * GRID_DT_S)[0], atol=1e-9)


def test_the_swap_is_faster_than_before_and_above_its_floors():
    """grid-64's 0.6 m head-on swap at half a reach aside: at most 58 grid steps (55 when written; round
    21S's uniform slow-down of the chord's profile took 64), and never below the two lower bounds of any
    flight along that path: the speed-and-acceleration floor and the chord flown straight rest to rest."""
    delta, w = np.array([0.6, 0.0, 0.0]), np.array([0.0, 0.5 * REACH_M, 0.0])
    law = quadratic_law(np.zeros(3), delta, w, LIMITS, GRID_DT_S)
    assert law.steps <= 58
    assert law.duration_s >= speed_accel_floor_s(delta, w, LIMITS)
    assert law.duration_s >= rest_to_rest(0.6, LIMITS, GRID_DT_S).duration_s


def test_the_floor_of_a_straight_path_is_the_bang_bang_time():
    """No bulge: the speed-and-acceleration floor over 0.6 m at 4 m/s^2 (the speed limit not reached) is
    2 sqrt(d / A) = 0.7746 s, to the floor's sampling."""
    got = speed_accel_floor_s(np.array([0.6, 0.0, 0.0]), np.zeros(3), LIMITS)
    assert abs(got - 2.0 * np.sqrt(0.6 / 4.0)) < 2e-3


def test_the_law_is_the_same_when_computed_again():
    """Deterministic: the law computed afresh (its cache cleared) is the same to the bit."""
    args = (np.zeros(3), np.array([0.85, 0.0, 0.0]), np.array([0.0, 0.25, 0.0]), LIMITS, GRID_DT_S)
    first = quadratic_law(*args)
    _cached_law.cache_clear()
    _shape_law.cache_clear()
    again = quadratic_law(*args)
    assert again.steps == first.steps and np.array_equal(again.half_jerk, first.half_jerk)


def test_a_joint_move_conflicting_leaving_together_is_staggered():
    """grid-64 by type's v012+v020+v027+v028 (v028 flies to v020's start, v012 to v028's): no joint move of
    it is conflict-free with every member leaving at once, a staggered one is, leaves v020 at once and
    keeps each member's moves (only delayed)."""
    _, _, problem = _assigned("grid", 64)
    members = tuple(sorted(problem.names.index(n) for n in ("v012", "v020", "v027", "v028")))
    moves = joint_moves(problem, members, checked=False)
    assert moves and not any(conflict_free(problem, jm) for jm in moves)
    fit = next(f for f in (fitted(problem, jm) for jm in moves) if f is not None)
    assert "staggered" in fit.label and conflict_free(problem, fit)
    src = next(jm for jm in moves if fit.label.startswith(jm.label + ", staggered"))
    i020 = members.index(problem.names.index("v020"))
    assert fit.moves[i020][0][0] == 0
    for legs, base in zip(fit.moves, src.moves):
        assert [mv for _, mv in legs] == [mv for _, mv in base]
        assert len({k - k0 for (k, _), (k0, _) in zip(legs, base)}) <= 1
