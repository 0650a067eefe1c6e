"""The bound on a vehicle's predicted tracking error in any plan the swarm layer can time
(proxplan.planner.swarm.tracking_bound): the chain programme against brute force, the bound against
the verifier's own prediction on chains of moves it was not computed on, and the keep-outs it grows."""

from __future__ import annotations

import functools

import numpy as np
import pytest

from proxplan.physics import BUILTIN_VEHICLES, KinematicLimits
from proxplan.planfile import VehicleTrajectory, scenario_from_dict
from proxplan.planner.formations import grid_reshuffle
from proxplan.planner.swarm import swarm_problem
from proxplan.planner.swarm.problem import tracking_growth_m
from proxplan.planner.swarm.tracking_bound import chain_bound_m, group_limits, held_bound_m, tracking_bound_m
from proxplan.planner.swarm.tracks import GRID_DT_S, GridTrack
from proxplan.planner.timing.paths import common_grid
from proxplan.planner.timing.plan_grid import DT_S
from proxplan.planner.timing.profile import LineMove, rest_to_rest
from proxplan.verify import tracking_along_plan

LIMITS = KinematicLimits(2.0, 4.0, 16.0)  # the built-in types' measured limits, m/s, m/s^2, m/s^3
LONGEST_M = 8.0  # the longest straight move of the chains below fits in this, m


def _brute_chain(table: np.ndarray, durations: list[int], *, held: bool = False) -> float:
    """The largest sum of ``table[m, t - start]`` over chains of non-overlapping moves (each move m
    over [start, start + durations[m]), later moves starting at or after the earlier ones end),
    evaluated at every time t of the window (``held``: only where the chain's last move has ended):
    every chain enumerated."""
    n_moves, h = table.shape
    best = 0.0

    def grow(t_eval: int, next_end: int, total: float) -> None:
        # add an earlier move that ends at or before next_end (its start >= 0 back from t_eval)
        nonlocal best
        best = max(best, total)
        for m in range(n_moves):
            for end in range(next_end, -1, -1):
                start = end - durations[m]
                age = t_eval - start
                if start < 0 or age >= h:
                    continue
                grow(t_eval, start, total + table[m, age])

    for t_eval in range(h):
        for m in range(n_moves):
            for start in range(0, t_eval + 1):
                if held and t_eval - start < durations[m]:
                    continue  # the last move still flies
                grow(t_eval, start, table[m, t_eval - start])
    return best


def test_the_chain_programme_equals_brute_force():
    rng = np.random.default_rng(3)
    for _ in range(5):
        table = rng.uniform(0.0, 1.0, size=(3, 9))
        durations = [int(d) for d in rng.integers(1, 4, size=3)]
        assert chain_bound_m(list(table), np.array(durations)) == pytest.approx(_brute_chain(table, durations))


@functools.lru_cache(maxsize=1)
def _bound_m() -> float:
    return tracking_bound_m(BUILTIN_VEHICLES["crazyflie-2.1"], (LIMITS,), LONGEST_M)


def _chain_error_m(moves_spec: list[tuple[np.ndarray, int]], first_step: int = 2) -> float:
    """Largest predicted |error| of a Crazyflie 2.1 flying rest-to-rest moves (delta m, then a rest
    of that many swarm grid steps), as the swarm layer times and samples them, m."""
    return float(_chain_errors(moves_spec, first_step)[0].max())


def _chain_errors(moves_spec: list[tuple[np.ndarray, int]], first_step: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """The predicted |error| (m) of the chain of :func:`_chain_error_m` on the verifier's grid, and the
    same at the samples where the vehicle is held (no move under way), m."""
    vehicle = BUILTIN_VEHICLES["crazyflie-2.1"]
    p, k, moves = np.zeros(3), first_step, []
    for delta, wait in moves_spec:
        move = LineMove(p, p + delta, rest_to_rest(float(np.linalg.norm(delta)), LIMITS, GRID_DT_S))
        moves.append((k, move))
        k += move.steps + wait
        p = move.end_m
    path = GridTrack(0, 0, np.zeros(3), moves).timed_path()
    grid = common_grid(path.duration_s + 3.0, DT_S)
    pos, vel, acc = path.sample(grid)
    tr = VehicleTrajectory("v", "crazyflie-2.1", vehicle, grid.copy(), pos, vel, acc)
    t = np.arange(0.0, float(grid[-1]) + 0.005, 0.01)
    err = np.linalg.norm(tracking_along_plan(tr, t).error_m, axis=1)
    flying = np.zeros(t.size, dtype=bool)
    for k, move in moves:
        flying |= (t >= k * GRID_DT_S - 1e-9) & (t <= (k + move.steps) * GRID_DT_S + 1e-9)
    return err, err[~flying]


def test_the_bound_holds_on_chains_it_was_not_computed_on():
    """Chains of moves of random lengths, directions (any azimuth, some climbing), rests and start
    phases, and the chains that add most (the same line, rests near the loop's period): the
    verifier's own prediction stays within the bound."""
    rng = np.random.default_rng(7)
    bound = _bound_m()
    errors = []
    for _ in range(6):
        spec = []
        for _ in range(int(rng.integers(2, 5))):
            az, el = rng.uniform(0.0, 2.0 * np.pi), rng.choice([0.0, 0.0, rng.uniform(-0.6, 0.6)])
            u = np.array([np.cos(az) * np.cos(el), np.sin(az) * np.cos(el), np.sin(el)])
            spec.append((rng.uniform(0.05, 3.0) * u, int(rng.integers(0, 40))))
        errors.append(_chain_error_m(spec, first_step=int(rng.integers(1, 4))))
    x = np.array([1.0, 0.0, 0.0])
    for d1, d2, wait in ((2.0, 0.5, 2), (0.5, 0.5, 8), (3.0, 3.0, 20), (1.0, 1.0, 40)):
        errors.append(_chain_error_m([(d1 * x, wait), (d2 * x, wait), (d1 * x, 0)]))
    assert max(errors) <= bound, (errors, bound)
    assert max(errors) > 0.3 * bound  # the chains exercise it (a bound far above them would be vacuous)


def test_group_limits_are_every_least_of_own_and_others():
    slow = KinematicLimits(1.0, 2.0, 8.0)
    odd = KinematicLimits(3.0, 1.0, 20.0)
    got = set(group_limits([LIMITS, slow, odd, LIMITS], LIMITS))
    assert got == {LIMITS, slow, KinematicLimits(2.0, 1.0, 16.0), KinematicLimits(1.0, 1.0, 8.0)}


def test_the_keepouts_grow_by_the_tracking_bound_of_each_type():
    """Moving, a pair's keep-out grows by its two vehicles' bounds; both at rest, by their bounds while
    held (round 37Z: the verifier adds the tube only while either moves, the deflections always)."""
    sc = scenario_from_dict(grid_reshuffle(4, types=["crazyflie-2.1"]), label="test")
    growth = tracking_growth_m(sc)
    held = tracking_growth_m(sc, held=True)
    assert set(growth) == set(sc.vehicles) == set(held) and len(set(growth.values())) == len(set(held.values())) == 1
    g, h = next(iter(growth.values())), next(iter(held.values()))
    assert 0.0 < h < g
    plain = swarm_problem(sc, tracking_bound=False)
    grown = swarm_problem(sc)
    for rest, pair_growth in ((True, 2.0 * h), (False, 2.0 * g)):
        ko, kg = plain.keepouts[(0, 0)], grown.keepouts[(0, 0)]
        edge = ko.separation_m + (ko.w_rest_m if rest else ko.w_move_m)  # the plain keep-out's edge, m
        assert not ko.conflict(np.array([[edge + 1e-4, 0.0, 0.0]]), rest=rest)[0]
        assert kg.conflict(np.array([[edge + pair_growth - 1e-4, 0.0, 0.0]]), rest=rest)[0]
        assert not kg.conflict(np.array([[edge + pair_growth + 1e-4, 0.0, 0.0]]), rest=rest)[0]
    assert grown.reach_xy_m == pytest.approx(plain.reach_xy_m + 2.0 * g)


@functools.lru_cache(maxsize=1)
def _held_bound_m() -> float:
    return held_bound_m(BUILTIN_VEHICLES["crazyflie-2.1"], (LIMITS,), LONGEST_M)


def test_the_held_programme_equals_brute_force():
    rng = np.random.default_rng(5)
    for _ in range(5):
        table = rng.uniform(0.0, 1.0, size=(3, 9))
        durations = [int(d) for d in rng.integers(1, 4, size=3)]
        got = chain_bound_m(list(table), np.array(durations), held=True)
        assert got == pytest.approx(_brute_chain(table, durations, held=True))
        assert got <= chain_bound_m(list(table), np.array(durations))


def test_the_held_bound_holds_where_chains_rest_and_is_below_the_bound():
    """The verifier's prediction at the samples where a chain holds still (after a move, before the
    next): within the held bound, which is below the bound while moving."""
    rng = np.random.default_rng(11)
    x = np.array([1.0, 0.0, 0.0])
    specs = [[(d1 * x, wait), (d2 * x, wait), (d1 * x, 0)] for d1, d2, wait in ((2.0, 0.5, 2), (0.5, 0.5, 8))]
    for _ in range(2):
        az = rng.uniform(0.0, 2.0 * np.pi)
        u = np.array([np.cos(az), np.sin(az), 0.0])
        specs.append([(rng.uniform(0.05, 3.0) * u, int(rng.integers(0, 40))) for _ in range(3)])
    held = [_chain_errors(spec)[1] for spec in specs]
    worst = max(float(e.max()) for e in held)
    assert worst <= _held_bound_m() < _bound_m()
    assert worst > 0.3 * _held_bound_m()  # the chains exercise it
