"""Stop 62 round 24A: the departure query along a line in one pass (``DepartureIndex.line_forbidden``:
the pairs of ``line_pairs``, gathered from the near segments only, windowed only where they conflict)
answers what the trees' pairs answer, on random occupancies and windows, and a whole swarm plan is
the same, track for track, with the line pass as with every departure query asked by the trees."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.planfile import scenario_from_dict
from proxplan.planner.formations import corridor, grid_reshuffle
from proxplan.planner.swarm.departures import DepartureIndex, covered
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.plan import swarm_timed
from proxplan.planner.swarm.problem import swarm_problem
from proxplan.planner.swarm.tracks import GRID_DT_S
from proxplan.planner.timing import CORNER_DEVIATION_M
from proxplan.planner.timing.profile import RunMove

from .test_swarm_departures import HORIZON, _line, _random_track


def _by_trees(occ: Occupancy, agent: int, q: np.ndarray, lo: int, hi: int) -> np.ndarray:
    """The departure query answered from the trees' pairs (``tree_pairs``), any move."""
    ix = occ._departure_index()
    ta = int(occ.problem.type_index[agent])
    rows, kk = ix.tree_pairs(q, occ._reach_of(ta), lo, hi)
    lo_d, hi_d = np.maximum(ix.t0[rows] - kk, lo), np.minimum(ix.t1[rows] - kk, hi)
    keep = (hi_d > lo_d) & ((ix.ag[rows] != agent) if agent in occ.tracks else True)
    rows, kk, lo_d, hi_d = rows[keep], kk[keep], lo_d[keep], hi_d[keep]
    h = occ.stack(ta, False).conflict(ix.P[rows] - q[kk], ix.ty[rows])
    return covered(lo_d[h], hi_d[h], occ.horizon)


@pytest.mark.parametrize("seed", range(8))
def test_line_pass_answers_what_the_trees_answer(seed):
    problem = swarm_problem(scenario_from_dict(grid_reshuffle(9, seed=4), label="test"))
    rng = np.random.default_rng(100 + seed)
    me = int(rng.integers(0, problem.n_agents))
    centre = 0.5 * (problem.starts_m[me] + problem.goals_m[me])
    tracks = [_random_track(problem, a, rng, centre) for a in range(problem.n_agents) if a != me]
    if seed % 2:  # its own track in the occupancy: no obstacle to itself (left out by agent)
        tracks.append(_random_track(problem, me, rng, centre))
    occ = Occupancy(problem, tracks, HORIZON)
    ix: DepartureIndex = occ._departure_index()
    ta = int(problem.type_index[me])
    s, g = problem.starts_m[me], problem.goals_m[me]
    via = centre + np.r_[rng.uniform(-0.6, 0.6, 2), 0.0]
    moves = [
        _line(problem, me, s, g).positions(),
        _line(problem, me, via, via + np.r_[0.3, -0.2, 0.0]).positions(),
        RunMove(np.array([s, via, g]), problem.limits[me], GRID_DT_S, deviation_m=CORNER_DEVIATION_M).positions(),
    ]
    asked = 0
    for q in moves:
        for lo, hi in [(0, HORIZON)] + [tuple(sorted(rng.integers(0, HORIZON, 2).tolist())) for _ in range(6)]:
            if hi <= lo:
                continue
            exclude = me if me in occ.tracks else -1
            got = ix.line_forbidden(q, occ._reach_of(ta), lo, hi, exclude, occ.stack(ta, False).conflict_rz, HORIZON)
            if got is None:  # not forward along a line: the trees answer it (forbidden_departures)
                continue
            asked += 1
            want = _by_trees(occ, me, q, lo, hi)
            np.testing.assert_array_equal(got, want)
            np.testing.assert_array_equal(occ.forbidden_departures(me, q, lo, hi), want)
    assert asked >= 7, "the straight moves must be asked along their line"


@pytest.mark.parametrize("layout", ["corridor", "grid"])
def test_swarm_plan_is_the_same_with_every_query_by_the_trees(layout, monkeypatch):
    """A whole swarm plan (prioritised planning, re-timing, makespan repair, whatever the layout
    takes) with the line pass, then with ``line_forbidden`` answering None (every query by the
    trees): the same stage and the same tracks, sample for sample."""
    doc = corridor(12) if layout == "corridor" else grid_reshuffle(16, seed=2)
    runs = []
    along = DepartureIndex.line_forbidden
    answered = [0]

    def counted(self, *args, **kwargs):
        got = along(self, *args, **kwargs)
        answered[0] += got is not None
        return got

    for line_pass in (True, False):
        monkeypatch.setattr(DepartureIndex, "line_forbidden", counted if line_pass else lambda self, *a, **k: None)
        timed, info = swarm_timed(scenario_from_dict(doc, label="test"))
        runs.append((timed, info))
    assert answered[0] > 100, "the plan must ask the line pass"
    (a, ia), (b, ib) = runs
    assert ia.stage == ib.stage and ia.makespan_s == ib.makespan_s
    assert a.keys() == b.keys()
    for name in a:
        np.testing.assert_array_equal(a[name].knot_t_s, b[name].knot_t_s)
        t = np.arange(0.0, a[name].duration_s + 0.1, 0.01)
        np.testing.assert_array_equal(a[name].sample(t)[0], b[name].sample(t)[0])
