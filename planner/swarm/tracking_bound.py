"""A bound, known before planning, on how far the verifier will predict a vehicle to be off any plan
the swarm layer can time for it: its tracking error along its own reference
(:func:`proxplan.verify.tracking.tracking_along_plan`, the one implementation the verifier uses,
docs/flying.md "A vehicle on its own reference"). The swarm layer grows its keep-outs by it
(:func:`proxplan.planner.swarm.problem.swarm_problem`), as the verifier grows each vehicle's tube,
so its first plan is not rejected by millimetres and planned a second time.

**What the swarm layer flies.** Every track is a chain of straight rest-to-rest moves
(:class:`~proxplan.planner.timing.profile.LineMove`; flights through waypoints are off by default,
``SwarmOptions.through_waypoints``) with rests of any length between them, each move the
time-optimal jerk-limited profile over its distance at a set of limits L (the vehicle's own, or in
a lock-step group the element-wise least of the group's), stretched in time to whole grid steps
(:func:`~proxplan.planner.timing.profile.rest_to_rest`); a lock-step move shorter than its group's
longest flies that profile scaled by a factor <= 1 along its own line.

**Why the bound holds.** The prediction is the response of a linear time-invariant loop
(:mod:`proxplan.physics.tracking_loop`) to the plan's samples, and sampling is linear: the error of
a chain is the sum of the errors of its moves, each flown alone from rest and shifted to its start
(measured: a 2 m move followed by a 0.5 m one 0.05 s later, along the same line, within 0.5 mm
of the sum at every sample, the largest errors 0.02 mm apart; the turn of the heading on a diagonal
is the one term that is not linear: 1.4 mm from the sum for a 2 m move along x followed by a 0.5 m
move along y, the same largest error). The norm of a sum is at most the sum of the norms,
with equality for a suitable turn between the moves, so the largest error of any chain is

    B = max over moves m and times i since m started of  n_m(i) + F(i),
    F(u) = max(F(u + 1), max over moves m' of n_m'(u + E_m') + F(u + E_m'))

with n_m(i) the error norm of move m alone i samples after it started (on the verifier's grid,
:data:`VERIFY_DT_S`), E_m its duration in samples, and F(u) the largest sum over the earlier moves
of a chain whose last earlier move ended at least u samples before (a dynamic programme over the
verifier's grid, :func:`chain_bound_m`). The moves m range over a family: distances of
:data:`DISTANCE_FRACTIONS` of the distance at which the profile first reaches the speed limit (up
to it the profile changes shape), then that distance plus a cruise of :data:`CRUISE_S` (the error
peaks 1.6 s into a cruise at 2 m/s, 4 m/s^2, 16 m/s^3 and is the same for longer moves), none
beyond the workspace's diagonal; along x, the horizontal diagonal and z (the heading's turn is
largest on the diagonal: 0 -> 15 -> 30 -> 45 degrees, 0.998 -> 1.002 -> 1.010 -> 1.014 cm on
a 2 m move); at every set of limits
a group of the scenario's vehicles can fly at. A scaled move's error is the member's scaled by its
factor <= 1; a rest adds nothing. Each move counts until :data:`SETTLE_S` after its end (what is
left then is at most 0.4 mm per move on the family of the built-in types). The hold after the end
(the loop's modal bound) is the floor. The family is finite: the bound is the maximum over it (a
denser one, 16 distances counted for 8 s, gave 2.46 cm against 2.43 cm for a Crazyflie 2.1).

**While the vehicle is held** (:func:`held_bound_m`; issue 37, round 37Z). The verifier grows a pair's
keep-out by the tube only while either vehicle moves, but by both vehicles' predicted deflections at
every sample, at rest too (:func:`proxplan.verify.pair_checks.check_pairs`: tube = tracking_margin_m
while moving + d_a + d_b). A vehicle the swarm layer holds (between moves, at its goal) is past the
end of its last move, so its tracking error there is bounded by the same programme with the last move
m counted only from its end on:

    B_held = max over moves m and times i >= E_m of  n_m(i) + F(i),

and the hold after the plan's end (the verifier's last sample) as the floor; before its first move a
vehicle's error is zero. B_held <= B: the swarm layer's keep-out between two held vehicles grows by
their two B_held, not by their B (:func:`proxplan.planner.swarm.problem.swarm_problem`).

World frame; m, s.
"""

from __future__ import annotations

import functools
import math
from itertools import combinations

import numpy as np

from proxplan.physics import KinematicLimits, Vehicle
from proxplan.planfile import VehicleTrajectory
from proxplan.planner.ties import rounded_up
from proxplan.planner.timing.profile import rest_to_rest
from proxplan.verify import tracking_along_plan

VERIFY_DT_S = 0.01  # the verifier's grid (verify_plan's dt_fine_s default), s
PLAN_DT_S = 0.05  # the plan's sample step (planner.timing.plan_grid.DT_S), s
GRID_DT_S = 0.025  # the swarm layer's grid (swarm.tracks.GRID_DT_S): moves start on it, s
SETTLE_S = 5.0  # a move's error counts until this long after its end (module docstring), s
# distances of the family, as fractions of the distance at which the profile first reaches the
# speed limit (the profile changes shape up to it: no cruise) ...
DISTANCE_FRACTIONS = (0.05, 0.1, 0.2, 0.3, 0.45, 0.6, 0.8, 1.0)
# ... and then that distance plus a cruise of these durations, s (the error peaks during the cruise,
# 1.6 s after the start at 2 m/s, 4 m/s^2, 16 m/s^3, and is the same for longer ones), as long as
# the move fits the workspace's diagonal
CRUISE_S = (0.5, 1.0, 2.0, 4.0)
# The bound is rounded UP to a multiple of this, m (round 37V, issue 37: "the same seed gives the same plan on any
# machine"). It is made through numpy, whose SIMD kernels are picked at run time, and its last bits differ with them:
# 0.024008902785347490 m (AVX-512) vs 0.024008902785347504 m (AVX2) for a Crazyflie 2.1, up to 1.2e-14 m on a
# pair's w. Every keep-out's w, reach, lane offset and waypoint is built from it, so an exact threshold downstream
# decided differently on the two paths (a right angle's cosine, round 37U). Rounded to a multiple, it is the same
# float on both unless a multiple lies between the two values (odds ~ 1e-14 / 1e-9 = 1e-5 per bound).
# Derivation. Below: the float error of the bound. It is a loop response over at most ~2000 samples of the
# verifier's grid (a move across the workspace's diagonal plus SETTLE_S, at VERIFY_DT_S), then a sum over a chain of
# ~10-20 moves: relative error <~ 2000 x 1.1e-16 = 2e-13, so <~ 1e-14 m on a 2.5 cm bound (measured: 1.2e-14 m,
# 5e-13 relative); 1e-9 m is 1e5 times that. Above: what a plan resolves. The verifier's separation test has a
# 1e-6 m tolerance (verify/pair_checks.py, ``d < sep + tube - 1e-6``) and the swarm layer compares positions in whole
# millimetres (problem.GROWTH_M): rounding up grows a keep-out by < 1e-9 m, 1e3 below the first, 1e6 below the
# second. Conservative: the bound only grows. (The same value as planner.ties.LENGTH_RESOLUTION_M, derived alike.)
TRACKING_BOUND_RESOLUTION_M = 1e-9
DIRECTIONS = (  # unit vectors: x, the horizontal diagonal (the heading turns most), z
    (1.0, 0.0, 0.0),
    (math.sqrt(0.5), math.sqrt(0.5), 0.0),
    (0.0, 0.0, 1.0),
)

__all__ = ["TRACKING_BOUND_RESOLUTION_M", "chain_bound_m", "group_limits", "held_bound_m", "tracking_bound_m"]


def full_speed_distance_m(limits: KinematicLimits) -> float:
    """Distance of the shortest rest-to-rest move that reaches the speed limit, m: accelerating
    to v takes v/a + a/j (v >= a^2/j) or 2 sqrt(v/j) (else), covering v/2 of that time each way."""
    v, a, j = limits.max_speed_mps, limits.max_accel_mps2, limits.max_jerk_mps3
    t_up = v / a + a / j if v >= a * a / j else 2.0 * math.sqrt(v / j)
    return v * t_up


def group_limits(limits: list[KinematicLimits], own: KinematicLimits) -> list[KinematicLimits]:
    """Every set of limits a vehicle with ``own`` limits can fly at in a lock-step group of vehicles
    with ``limits`` (the scenario's): the element-wise least of ``own`` and any subset of the others."""
    others = sorted(set(limits) - {own}, key=lambda k: (k.max_speed_mps, k.max_accel_mps2, k.max_jerk_mps3))
    out = {own}
    for r in range(1, len(others) + 1):
        for sub in combinations(others, r):
            group = (own, *sub)
            out.add(
                KinematicLimits(
                    min(x.max_speed_mps for x in group),
                    min(x.max_accel_mps2 for x in group),
                    min(x.max_jerk_mps3 for x in group),
                )
            )
    return sorted(out, key=lambda k: (k.max_speed_mps, k.max_accel_mps2, k.max_jerk_mps3))


def family_distances_m(limits: KinematicLimits, longest_m: float) -> list[float]:
    """The family's move distances at ``limits``, m, none beyond ``longest_m`` (the longest straight
    move the scenario allows; the longest itself included)."""
    full = full_speed_distance_m(limits)
    out = [f * full for f in DISTANCE_FRACTIONS] + [full + limits.max_speed_mps * c for c in CRUISE_S]
    return sorted({min(d, longest_m) for d in out if d > 0.0})


def _move_error_m(vehicle: Vehicle, limits: KinematicLimits, delta_m: np.ndarray) -> tuple[np.ndarray, int, float]:
    """The error norm (M,), m, of ``vehicle`` flying one rest-to-rest move by ``delta_m`` (3,), m,
    alone, on the verifier's grid from the move's start until :data:`SETTLE_S` after its end; its
    duration in samples; and the hold bound after that (m). The plan is sampled as the swarm
    layer's plans are, on the plan's step, the move starting on one (the other phase of the swarm
    grid changes it by < 3 %: 0.66 / 0.68 cm on 0.5 m)."""
    dist = float(np.linalg.norm(delta_m))
    prof = rest_to_rest(dist, limits, GRID_DT_S)
    start = PLAN_DT_S  # one plan step at rest first, as every plan starts
    end = start + prof.duration_s
    t = np.arange(int(math.ceil((end + SETTLE_S) / PLAN_DT_S)) + 1) * PLAN_DT_S
    pva = np.array([prof.at(float(tk - start)) for tk in t])  # (K, 3): distance, speed, acceleration
    unit = np.asarray(delta_m, dtype=float) / dist
    tr = VehicleTrajectory("bound", vehicle.name, vehicle, t, pva[:, :1] * unit, pva[:, 1:2] * unit, pva[:, 2:3] * unit)
    grid = np.arange(0.0, float(t[-1]) + VERIFY_DT_S / 2, VERIFY_DT_S)
    resp = tracking_along_plan(tr, grid)
    first = int(round(start / VERIFY_DT_S))
    norm = np.linalg.norm(resp.error_m, axis=1)[first:]
    return norm, int(round((end - start) / VERIFY_DT_S)), float(resp.hold_error_m)


def chain_bound_m(norms_m: list[np.ndarray], durations: np.ndarray, *, held: bool = False) -> float:
    """The largest sum of error norms of a chain of moves (module docstring): ``norms_m`` each
    move's error norm alone, m, by samples since its start (zero after its last sample);
    ``durations`` (M,) in samples. ``held``: only at times after the chain's last move ended
    (i >= E_m, the vehicle held: B_held of the module docstring)."""
    h = max(n.size for n in norms_m)
    table = np.zeros((len(norms_m), h))
    for k, n in enumerate(norms_m):
        table[k, : n.size] = n
    dur = np.maximum(np.asarray(durations, dtype=np.int64), 1)
    f = np.zeros(h + 1)  # f[u]: the earlier moves' largest sum, the last of them ended >= u samples before
    for u in range(h - 1, -1, -1):
        idx = u + dur
        ok = idx < h
        best = f[u + 1]
        if ok.any():
            best = max(best, float((table[ok, idx[ok]] + f[idx[ok]]).max()))
        f[u] = best
    total = table + f[None, :h]
    if held:
        total = np.where(np.arange(h)[None, :] >= dur[:, None], total, 0.0)
    return float(total.max())


@functools.lru_cache(maxsize=64)
def _family_errors(
    vehicle: Vehicle, limits: tuple[KinematicLimits, ...], longest_m: float
) -> tuple[tuple[np.ndarray, ...], np.ndarray, float]:
    """The family's moves (module docstring) of ``vehicle`` at any of ``limits``, up to ``longest_m``
    (m): each move's error norm alone (m, by samples since its start), durations (samples) and the
    largest hold bound after a move (m). Cached per process (both bounds read it)."""
    norms, durations, holds = [], [], []
    for lim in limits:
        for dist in family_distances_m(lim, longest_m):
            for direction in DIRECTIONS:
                n, e, hold = _move_error_m(vehicle, lim, dist * np.asarray(direction))
                norms.append(n)
                durations.append(e)
                holds.append(hold)
    return tuple(norms), np.array(durations), max(holds)


@functools.lru_cache(maxsize=64)
def tracking_bound_m(vehicle: Vehicle, limits: tuple[KinematicLimits, ...], longest_m: float) -> float:
    """The bound (module docstring), m, for ``vehicle`` flying moves of up to ``longest_m`` (m) at
    any of ``limits`` (:func:`group_limits`), rounded up to :data:`TRACKING_BOUND_RESOLUTION_M` (the same float
    whatever numpy's SIMD kernels)."""
    norms, durations, hold = _family_errors(vehicle, limits, longest_m)
    return rounded_up(max(chain_bound_m(list(norms), durations), hold), TRACKING_BOUND_RESOLUTION_M)


@functools.lru_cache(maxsize=64)
def held_bound_m(vehicle: Vehicle, limits: tuple[KinematicLimits, ...], longest_m: float) -> float:
    """B_held (module docstring), m: the bound on ``vehicle``'s tracking error while it is held after
    any chain of the family's moves (as :func:`tracking_bound_m`, the last move counted from its end
    on; the hold after the plan's end the floor), rounded up alike; at most :func:`tracking_bound_m`."""
    norms, durations, hold = _family_errors(vehicle, limits, longest_m)
    return rounded_up(max(chain_bound_m(list(norms), durations, held=True), hold), TRACKING_BOUND_RESOLUTION_M)
