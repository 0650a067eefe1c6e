"""The wavefront (proxplan.planner.swarm.wave, wave_marks): its cheaper bookkeeping (cells marked only as far
as asked, and each layer spread only over the front's bounding box) gives the same occupancy and
the same reached cells as marking every layer and spreading over the whole grid (the definition);
its height-aware discs are as wide as the keep-out at the heights the route flies at, no wider than
the widest keep-out, and hold every cell centre in conflict."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.planfile import scenario_from_dict
from proxplan.planner.formations import LAYOUTS
from proxplan.planner.swarm import swarm_problem
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.reserve import reserved_track
from proxplan.planner.swarm.wave import _spread, dilated, free_layers
from proxplan.planner.swarm.wave_grid import CELL_M, margin_box, route_heights
from proxplan.planner.swarm.wave_marks import OccupiedCells, disc_offsets

HORIZON = 400


def _world(seed: int) -> tuple[OccupiedCells, np.ndarray, np.ndarray]:
    """Random discs (moving keys, some off the grid) and parked vehicles on a 40 x 30 grid of 60
    layers: the lazily marked occupancy, the same marked fully by the definition, a static mask."""
    rng = np.random.default_rng(seed)
    shape = (60, 40, 30)
    occ = OccupiedCells(*shape)
    full = np.zeros(shape, dtype=bool)
    for _ in range(12):
        radius = float(rng.uniform(1.0, 4.5))
        n = int(rng.integers(5, 40))
        L = np.sort(rng.integers(0, shape[0], n))
        X, Y = rng.integers(-5, shape[1] + 5, n), rng.integers(-5, shape[2] + 5, n)
        occ.add(radius, L, X, Y)
        ox, oy = disc_offsets(radius)
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


def _problem(layout: str, n: int):
    return swarm_problem(scenario_from_dict(LAYOUTS[layout](n), label="test scenario"))


def test_horizontal_radius_bounds_the_keepout_over_its_height_band():
    """For random height bands, no relative vector with a height difference in the band and a
    horizontal distance beyond the radius conflicts; the radius never exceeds the widest reach, and
    a band over every height difference gives that reach."""
    problem = _problem("grid", 32)  # three vehicle types
    rng = np.random.default_rng(7)
    for ko in problem.keepouts.values():
        assert ko.horizontal_radius_m(-5.0, 5.0) == ko.reach_xy_m
        for _ in range(30):
            lo, hi = np.sort(rng.uniform(-0.8, 0.8, 2))
            r = ko.horizontal_radius_m(float(lo), float(hi))
            assert 0.0 <= r <= ko.reach_xy_m
            dz = np.linspace(lo, hi, 301)
            ang = rng.uniform(0.0, 2 * np.pi, dz.size)
            beyond = r + 1e-6
            d = np.column_stack([beyond * np.cos(ang), beyond * np.sin(ang), dz])
            assert not ko.conflict(d).any()


def test_route_heights_follow_progress_along_the_line():
    """The start's height at and behind the start (and beside it), the goal's at and beyond the
    goal, halfway at the midpoint; None for a move within a cell horizontally."""
    s, g = np.array([0.0, 0.0, 1.0]), np.array([2.0, 0.0, 1.5])
    z = route_heights(s, g, np.array([[0.0, 0.0], [-0.5, 0.3], [0.0, 0.7], [1.0, -0.4], [2.0, 0.0], [2.6, 0.0]]))
    assert np.allclose(z, [1.0, 1.0, 1.0, 1.25, 1.5, 1.5])
    assert route_heights(s, np.array([0.02, 0.0, 1.5]), np.zeros((1, 2))) is None


def test_discs_hold_every_conflicting_cell_centre_and_free_what_the_heights_allow():
    """pillar-64: a vehicle's wavefront grid against a neighbour parked at its start one layer
    above or below: every cell centre whose exact keep-out (at the route's height there) holds the
    neighbour is occupied at every layer; with the heights, fewer cells are occupied than with the
    widest disc at every height."""
    problem = _problem("pillar", 64)
    S = problem.starts_m
    a = 0
    other = np.flatnonzero(np.abs(S[:, 2] - S[a, 2]) > 0.2)
    b = int(other[np.argmin(np.linalg.norm(S[other, :2] - S[a, :2], axis=1))])
    occ = Occupancy(problem, [reserved_track(problem, b)], HORIZON)
    s, g = problem.starts_m[a], problem.goals_m[a]
    box = margin_box(problem, s, g)
    kw = dict(pace=0.8, grow_m=0.0)
    free = free_layers(occ, a, s, g, box, heights=True, **kw)
    wide = free_layers(occ, a, s, g, box, heights=False, **kw)
    nx, ny = free.shape[1:]
    ix, iy = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    xy = np.column_stack([box[0][0] + ix.ravel() * CELL_M, box[0][1] + iy.ravel() * CELL_M])
    z = route_heights(s, g, xy)
    d = S[b][None] - np.column_stack([xy, z])
    ko = problem.keepouts[(int(problem.type_index[a]), int(problem.type_index[b]))]
    hit = ko.conflict(d).reshape(nx, ny)
    assert hit.any()
    assert not (free & hit[None]).any()
    assert (~free).sum() < (~wide).sum()
