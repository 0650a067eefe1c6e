"""Round 30B: the windows' distances for many points at once (``bounds.window_gaps_m``, a k-d tree from
``GAP_TREE_POINTS`` points on) are the floats the point-by-point minimum over every cell gives, and the
assignment's certified pair costs (``swarm.obstacle_costs.pair_bounds_s``) built on them equal the
point-by-point form (``bounds.reach_through_s`` for every pair)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from proxplan.planfile import scenario_from_dict
from proxplan.planner.bounds import (
    GAP_TREE_POINTS,
    reach_through_s,
    slabs,
    window,
    window_gaps_m,
)
from proxplan.planner.formations import layout_doc
from proxplan.planner.swarm.obstacle_costs import pair_bounds_s


def _brute_gap_m(point: np.ndarray, win) -> float:
    d = np.linalg.norm(win.centres_m - point, axis=1) - win.half_diag_m
    return max(float(d.min()), 0.0)


def test_window_gaps_equal_every_cell_on_both_branches():
    sc = scenario_from_dict(layout_doc("pillar", 16, assign="by_type"))
    rng = np.random.default_rng(3)
    lo, hi = sc.workspace_min_m, sc.workspace_max_m
    slab = slabs(sc)[0]
    win = window(sc, slab.axis, slab.lo_m, 0.1)
    assert win.centres_m.shape[0] > 1000
    many = rng.uniform(lo, hi, size=(3 * GAP_TREE_POINTS, 3))
    # on cell centres and half way between two: ties among the nearest cells
    many[0] = win.centres_m[5]
    many[1] = 0.5 * (win.centres_m[5] + win.centres_m[6])
    got = window_gaps_m(many, win)
    few = window_gaps_m(many[: GAP_TREE_POINTS - 1], win)
    want = np.array([_brute_gap_m(p, win) for p in many])
    assert np.array_equal(got, want)  # the same floats, not close ones
    assert np.array_equal(few, want[: GAP_TREE_POINTS - 1])
    assert got[0] == 0.0 and got.max() > 0.5


def test_window_without_free_cells_is_infinitely_far():
    sc = scenario_from_dict(layout_doc("pillar", 16, assign="by_type"))
    slab = slabs(sc)[0]
    win = replace(window(sc, slab.axis, slab.lo_m, 0.1), centres_m=np.zeros((0, 3)))  # no free cell
    assert np.all(np.isinf(window_gaps_m(np.zeros((GAP_TREE_POINTS + 1, 3)), win)))
    assert math.isinf(reach_through_s(np.zeros(3), win, sc.vehicles[next(iter(sc.vehicles))].kinematic_limits))


def test_pair_bounds_equal_point_by_point():
    sc = scenario_from_dict(layout_doc("pillar", 16, assign="by_type"))
    names = list(sc.vehicles)
    got = pair_bounds_s(sc, names)
    tasks = [sc.vehicles[n] for n in names]
    want = np.zeros_like(got)
    for slab in slabs(sc):
        k = slab.axis
        for i, ti in enumerate(tasks):
            for g, tg in enumerate(tasks):
                s, e = np.asarray(ti.start_m, float), np.asarray(tg.goal_m, float)
                if s[k] < slab.lo_m and e[k] > slab.hi_m:
                    near, far = slab.lo_m, slab.hi_m
                elif s[k] > slab.hi_m and e[k] < slab.lo_m:
                    near, far = slab.hi_m, slab.lo_m
                else:
                    continue
                lim, rb = ti.kinematic_limits, ti.body_radius_m
                t = (
                    reach_through_s(s, window(sc, k, near, rb), lim)
                    + (slab.hi_m - slab.lo_m) / lim.max_speed_mps
                    + reach_through_s(e, window(sc, k, far, rb), lim)
                )
                want[i, g] = max(want[i, g], t)
    assert (want > 0).sum() > 10
    assert np.array_equal(got, want)
