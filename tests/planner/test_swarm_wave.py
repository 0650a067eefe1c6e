"""The wavefront's cheaper bookkeeping (proxplan.planner.swarm.wave): cells marked only as far as
asked, and each layer spread only over the front's bounding box, give the same occupancy and the
same reached cells as marking every layer and spreading over the whole grid (the definition)."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.planner.swarm.wave import _disc, _Occupied, _spread, dilated


def _world(seed: int) -> tuple[_Occupied, np.ndarray, np.ndarray]:
    """Random discs (moving keys, some off the grid) and parked vehicles on a 40 x 30 grid of 60
    layers: the lazily marked occupancy, the same marked fully by the definition, a static mask."""
    rng = np.random.default_rng(seed)
    shape = (60, 40, 30)
    occ = _Occupied(*shape)
    full = np.zeros(shape, dtype=bool)
    for _ in range(12):
        radius = float(rng.uniform(1.0, 4.5))
        n = int(rng.integers(5, 40))
        L = np.sort(rng.integers(0, shape[0], n))
        X, Y = rng.integers(-5, shape[1] + 5, n), rng.integers(-5, shape[2] + 5, n)
        occ.add(radius, L, X, Y)
        ox, oy = _disc(radius)
        for l_, x, y in zip(L, X, Y):
            for i, j in zip(x + ox, y + oy):
                if 0 <= i < shape[1] and 0 <= j < shape[2]:
                    full[l_, i, j] = True
        if rng.random() < 0.3:
            last, x, y = int(rng.integers(0, shape[0])), int(rng.integers(0, shape[1])), int(rng.integers(0, shape[2]))
            occ.park(radius, last, x, y)
            for i, j in zip(x + ox, y + oy):
                if 0 <= i < shape[1] and 0 <= j < shape[2]:
                    full[last:, i, j] = True
    static = rng.random(shape[1:]) > 0.1
    return occ, full, static


def _spread_whole_grid(full, static, start, goal, hold_from):
    """The definition: every layer over the whole grid (the 8-neighbourhood as the module's)."""
    n_layers = full.shape[0]
    free = ~full & static[None]
    reach = np.zeros(full.shape, dtype=bool)
    reach[0][start] = True
    for t in range(n_layers - 1):
        cur = reach[t]
        if t >= hold_from and cur[goal]:
            return t, reach
        nxt = dilated(cur) & free[t + 1] & free[t]
        reach[t + 1] = nxt
        if not nxt.any():
            return None, reach
    return None, reach


@pytest.mark.parametrize("seed", range(8))
def test_lazy_marks_and_windowed_front_equal_the_definition(seed):
    occ, full, static = _world(seed)
    rng = np.random.default_rng(100 + seed)
    for x, y in rng.integers(0, 30, (10, 2)):
        np.testing.assert_array_equal(occ.column(int(x), int(y)), full[:, x, y])
    start, goal = (2, 3), (35, 25)
    static[start] = static[goal] = True
    if seed % 2:  # a wall across the grid: the front never reaches the goal
        static[20, :] = False
    hold_from = int(rng.integers(0, 50))
    reach = np.zeros(full.shape, dtype=bool)
    t_goal = _spread(reach, occ, static, start, goal, hold_from)
    want_t, want_reach = _spread_whole_grid(full, static, start, goal, hold_from)
    assert t_goal == want_t
    np.testing.assert_array_equal(reach, want_reach)  # the same front, layer by layer
    assert (t_goal is None) == bool(seed % 2)
    occ.mark_upto(full.shape[0])
    np.testing.assert_array_equal(occ.layers, full)
