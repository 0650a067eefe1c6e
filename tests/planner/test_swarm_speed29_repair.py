"""Round 29B (issue 37): the lock-step conversion's pair search (exact: the same pairs as a brute-force
search over every pair of moves, so the same tracks) and the makespan repair's stall count restarted
only by a shorter plan (not exact: checked never longer here, and deterministic)."""

from __future__ import annotations

import numpy as np

from proxplan.planner.swarm import SwarmOptions
from proxplan.planner.swarm import lockstep as lockstep_module
from proxplan.planner.swarm.lockstep import REACH_GROWTH_M, _near_pairs, _pair_radius_m, segment_distance_xy_m
from proxplan.planner.swarm.makespan import budget, shorten_makespan
from proxplan.planner.swarm.occupancy import track_digest
from proxplan.planner.swarm.retime_stage import HORIZON_MARGIN_S
from proxplan.planner.swarm.tracks import GRID_DT_S


def _radius_by_rows(problem, ti, tj, dz_lo, dz_hi) -> np.ndarray:
    """The radius per pair as before round 29B: the distinct rows of four floats (np.unique, axis=0)."""
    rows = np.stack([ti, tj, dz_lo, dz_hi], axis=1)
    uniq, inv = np.unique(rows, axis=0, return_inverse=True)
    out = np.empty(uniq.shape[0])
    for k, (a, b, lo, hi) in enumerate(uniq.tolist()):
        ab = problem.keepouts[(int(a), int(b))].horizontal_radius_m(lo, hi)
        ba = problem.keepouts[(int(b), int(a))].horizontal_radius_m(-hi, -lo)
        out[k] = max(ab, ba)
    return out[np.asarray(inv).reshape(-1)]


def _moves(problem, n: int, seed: int):
    """``n`` random straight moves on a few heights, of the problem's types: short and long ones (the
    lattice's runs of 1-4 edges), some vertical, many within reach of each other."""
    rng = np.random.default_rng(seed)
    z = rng.choice([0.6, 0.9, 1.2, 1.5], size=n)
    p0 = np.column_stack([rng.uniform(-2.0, 2.0, n), rng.uniform(-2.0, 2.0, n), z])
    step = rng.choice([0.0, 0.3, 0.6, 1.2], size=(n, 1)) * rng.choice([-1.0, 1.0], size=(n, 2))
    p1 = p0 + np.column_stack([step, rng.choice([0.0, 0.0, 0.3], size=n)])
    types = rng.integers(0, int(np.max(problem.type_index)) + 1, size=n)
    return p0, p1, types


def _brute_pairs(problem, p0, p1, types) -> set[tuple[int, int]]:
    """Every pair i < j of moves within reach, tested exactly (no candidate search)."""
    i, j = np.triu_indices(p0.shape[0], k=1)
    d = segment_distance_xy_m(p0[i], p1[i], p0[j], p1[j])
    zlo, zhi = np.minimum(p0[:, 2], p1[:, 2]), np.maximum(p0[:, 2], p1[:, 2])
    ok = d < problem.reach_xy_m + REACH_GROWTH_M
    ok &= np.maximum(zlo[i] - zhi[j], zlo[j] - zhi[i]) < problem.reach_z_m + REACH_GROWTH_M
    i, j, d = i[ok], j[ok], d[ok]
    radius = _radius_by_rows(problem, types[i], types[j], zlo[j] - zhi[i], zhi[j] - zlo[i]) + REACH_GROWTH_M
    keep = d < radius
    return set(zip(i[keep].tolist(), j[keep].tolist(), strict=True))


def test_the_pair_radius_by_one_integer_key_is_the_radius_by_rows(stacked16):
    """The radius of every pair, by distinct rows keyed by one integer, equals the radius by np.unique
    over the rows of four floats (repeated rows, both orders of the types, negative heights)."""
    _, problem, _ = stacked16
    rng = np.random.default_rng(3)
    n_types = int(np.max(problem.type_index)) + 1
    ti, tj = rng.integers(0, n_types, 400), rng.integers(0, n_types, 400)
    lo = rng.choice([-0.6, -0.3, 0.0, 0.3], 400)
    hi = lo + rng.choice([0.0, 0.3], 400)
    assert np.array_equal(_pair_radius_m(problem, ti, tj, lo, hi), _radius_by_rows(problem, ti, tj, lo, hi))
    empty = np.zeros(0)
    assert _pair_radius_m(problem, empty.astype(int), empty.astype(int), empty, empty).shape == (0,)


def test_the_near_pairs_are_those_of_a_search_over_every_pair(stacked16, monkeypatch):
    """lockstep._near_pairs (candidates by the midpoints' tree, then the midpoint and height filters,
    then the exact distance once) gives exactly the pairs of a brute-force test of every pair, also in
    chunks smaller than the candidates (PAIR_CHUNK)."""
    _, problem, _ = stacked16
    for seed in range(3):
        p0, p1, types = _moves(problem, 300, seed)
        want = _brute_pairs(problem, p0, p1, types)
        got = _near_pairs(problem, p0, p1, types)
        assert len(want) > 100  # many pairs within reach: the test has something to miss
        assert set(map(tuple, got.tolist())) == want and len(got) == len(want)
    monkeypatch.setattr(lockstep_module, "PAIR_CHUNK", 257)
    got = _near_pairs(problem, p0, p1, types)
    assert set(map(tuple, got.tolist())) == want


def _repair(problem, before, on_makespan: bool):
    by_agent = dict(before)
    horizon = int(round((max(t.arrival_s for t in before.values()) + HORIZON_MARGIN_S) / GRID_DT_S))
    counts = shorten_makespan(
        problem, by_agent, horizon, through=False, max_plannings=budget(16), stall_on_makespan=on_makespan
    )
    return by_agent, counts


def _digest(by_agent) -> bytes:
    return b"".join(track_digest(by_agent[a]) for a in sorted(by_agent))


def test_the_stall_restarted_by_a_shorter_plan_only_is_never_longer_here_and_deterministic(stacked16):
    """grid-16's stacked plan repaired with the stall count restarted only where the latest arrival got
    earlier: a plan no longer than with every replacement restarting it, in no more plannings, and the
    same tracks when run again."""
    _, problem, before = stacked16
    old, old_counts = _repair(problem, before, on_makespan=False)
    new, new_counts = _repair(problem, before, on_makespan=True)
    end = max(t.arrival_step for t in before.values())
    assert max(t.arrival_step for t in new.values()) < end  # it shortens this plan
    assert max(t.arrival_step for t in new.values()) <= max(t.arrival_step for t in old.values())
    assert new_counts["plannings"] <= old_counts["plannings"]
    again, again_counts = _repair(problem, before, on_makespan=True)
    assert _digest(again) == _digest(new) and again_counts == new_counts


def test_the_stage_uses_the_module_default(stacked16, monkeypatch):
    """makespan_stage's repair follows makespan.STALL_ON_MAKESPAN (the same tracks as asked directly)."""
    from proxplan.planner.swarm import makespan as makespan_module
    from proxplan.planner.swarm.repair_stage import makespan_stage

    _, problem, before = stacked16
    for flag in (False, True):
        monkeypatch.setattr(makespan_module, "STALL_ON_MAKESPAN", flag)
        staged = dict(before)
        makespan_stage(problem, staged, SwarmOptions(through_waypoints="never"), progress=None, deadline=None)
        direct, _ = _repair(problem, before, on_makespan=flag)
        assert _digest(staged) == _digest(direct)
