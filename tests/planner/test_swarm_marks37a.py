"""The wavefront's marks by flat offsets (round 37A, proxplan.planner.swarm.wave_marks.mark_discs): a disc
written into a padded buffer by its centre's flat index plus the disc's flat offsets marks exactly the
grid cells that testing each disc cell against the grid's bounds marks (the definition), for centres on
the grid, just off it (within the disc's half-width, where part of the disc reaches the grid) and far
off it (no cell); a padding too narrow for the disc is refused; and OccupiedCells, which marks with it,
refuses an entry wider than its padding once the marks are begun (its buffer is sized for the entries
in at that moment)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from proxplan.planner.swarm.wave_grid import CELL_M
from proxplan.planner.swarm.wave_marks import OccupiedCells, _disc_key, disc_offsets, mark_discs


def _definition(shape, radius, layer, cx, cy) -> np.ndarray:
    out = np.zeros(shape, dtype=bool)
    ox, oy = disc_offsets(radius)
    for l_, x, y in zip(layer, cx, cy):
        for i, j in zip(x + ox, y + oy):
            if 0 <= i < shape[1] and 0 <= j < shape[2]:
                out[l_, i, j] = True
    return out


def _marked(shape, radius, layer, cx, cy, pad) -> np.ndarray:
    n_layers, nx, ny = shape
    buf = np.zeros((n_layers, nx + 2 * pad, ny + 2 * pad), dtype=bool)
    mark_discs(buf, pad, (nx, ny), _disc_key(radius), layer, cx, cy)
    return buf[:, pad : pad + nx, pad : pad + ny]


@pytest.mark.parametrize("seed", range(6))
def test_flat_offsets_mark_the_cells_of_the_definition(seed):
    rng = np.random.default_rng(seed)
    shape = (12, int(rng.integers(3, 30)), int(rng.integers(3, 30)))
    radius = float(rng.uniform(0.5, 6.0))
    half = math.isqrt(max(_disc_key(radius) - 1, 0))
    n = 200
    layer = rng.integers(0, shape[0], n)
    # centres on the grid, within the half-width off it and beyond it, on every side
    cx = rng.integers(-half - 3, shape[1] + half + 3, n)
    cy = rng.integers(-half - 3, shape[2] + half + 3, n)
    for pad in (2 * half, 2 * half + 3):
        got = _marked(shape, radius, layer, cx, cy, pad)
        np.testing.assert_array_equal(got, _definition(shape, radius, layer, cx, cy))


def test_centres_at_the_edges_of_the_half_width():
    """A centre exactly the half-width off the grid reaches its edge row; one more cell off, nothing."""
    shape, radius = (1, 10, 10), 3.5  # key 13: half-width 3
    half = math.isqrt(_disc_key(radius) - 1)
    assert half == 3
    cx = np.array([-half, -half - 1, 10 + half - 1, 10 + half, 4, 4])
    cy = np.array([4, 4, 5, 5, -half, 10 + half])
    layer = np.zeros(cx.size, dtype=np.int64)
    got = _marked(shape, radius, layer, cx, cy, 2 * half)
    want = _definition(shape, radius, layer, cx, cy)
    np.testing.assert_array_equal(got, want)
    assert want[0, 0, 4] and want[0, 9, 5] and want[0, 4, 0]  # the edge rows the near centres reach


def test_a_padding_narrower_than_twice_the_half_width_is_refused():
    buf = np.zeros((1, 14, 14), dtype=bool)
    with pytest.raises(ValueError, match="padding"):
        mark_discs(buf, 2, (10, 10), _disc_key(3.5), np.zeros(1, dtype=np.int64), np.array([0]), np.array([0]))


def test_occupied_cells_refuse_a_wider_entry_once_the_marks_are_begun():
    occ = OccupiedCells(8, 10, 10)
    occ.add(2.0, np.array([0, 3]), np.array([-2, 5]), np.array([5, 11]))
    occ.mark_upto(4)
    occ.add(1.5, np.array([5]), np.array([2]), np.array([2]))  # no wider: fine
    with pytest.raises(ValueError, match="wider than the padding"):
        occ.add(4.0, np.array([5]), np.array([2]), np.array([2]))
    with pytest.raises(ValueError, match="wider than the padding"):
        occ.park(4.0, 5, 2, 2)


def _marks_track_by_track(occ, agent, start_m, goal_m, box, *, pace: float, grow_m: float) -> np.ndarray:
    """others_marks without heights as it was before round 37A (the definition): each track's cells in
    turn, a disc of the widest keep-out round each, parked tracks from their last layer on; every layer
    marked."""
    from proxplan.planner.swarm.tracks import GRID_DT_S
    from proxplan.planner.swarm.wave_marks import others_marks

    p = occ.problem
    h = CELL_M
    layer_s = h * math.sqrt(2.0) / (pace * p.limits[agent].max_speed_mps)
    want, _ = others_marks(occ, agent, start_m, goal_m, box, pace=pace, grow_m=grow_m, heights=False)
    n_layers, nx, ny = want.shape
    ref = OccupiedCells(n_layers, nx, ny)
    lo = box[0]
    ta = int(p.type_index[agent])
    for tr in occ.near(np.r_[lo, -np.inf], np.r_[box[1], np.inf], agent):
        radius = (p.keepouts[(ta, tr.type)].reach_xy_m + grow_m) / h
        P = tr.positions_m
        lay = np.floor(np.arange(P.shape[0]) / (layer_s / GRID_DT_S) + 0.5).astype(np.int64)
        cx = np.round((P[:, 0] - lo[0]) / h).astype(np.int64)
        cy = np.round((P[:, 1] - lo[1]) / h).astype(np.int64)
        ref.add(radius, lay, cx, cy)
        if int(lay[-1]) < n_layers and not tr.vanishes:
            ref.park(radius, int(lay[-1]), int(cx[-1]), int(cy[-1]))
    ref.mark_upto(n_layers)
    want.mark_upto(n_layers)
    return want.layers, ref.layers


@pytest.mark.parametrize("layout", ["grid", "pillar"])
def test_marks_of_all_tracks_at_once_equal_track_by_track(layout):
    """others_marks lays every near track's samples end to end (round 37A): the same marks as track by
    track, with planned tracks (parked at their goals), predictions that vanish and reserved starts."""
    from proxplan.planfile import scenario_from_dict
    from proxplan.planner.formations import LAYOUTS
    from proxplan.planner.swarm import swarm_problem
    from proxplan.planner.swarm.occupancy import Occupancy
    from proxplan.planner.swarm.reserve import ideal_track, predicted_track, reserved_track
    from proxplan.planner.swarm.wave_grid import margin_box

    problem = swarm_problem(scenario_from_dict(LAYOUTS[layout](16), label="test scenario"))
    horizon = 400
    tracks = []
    for b in range(1, problem.n_agents):
        if b % 3 == 0:
            tracks.append(reserved_track(problem, b))
        elif b % 3 == 1:
            tracks.append(predicted_track(problem, b, hold_s=0.5))
        else:
            tracks.append(ideal_track(problem, b, horizon) or reserved_track(problem, b))
    occ = Occupancy(problem, tracks, horizon)
    a = 0
    s, g = problem.starts_m[a], problem.goals_m[a]
    for grow_m in (0.0, 0.05):
        got, want = _marks_track_by_track(occ, a, s, g, margin_box(problem, s, g), pace=0.8, grow_m=grow_m)
        assert want.any()
        np.testing.assert_array_equal(got, want)
