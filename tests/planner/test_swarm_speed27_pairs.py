"""Stop 65 round 27B: the departure query's pair test in one table lookup
(``GrownStack.conflict_rz``: squared horizontal distances and heights, the three tables flat) and the
line query's near segments scanned as one array (``DepartureIndex._line_near``) give the same
booleans and the same segments, in the same order, as the formulas they replace (written out here
as the references), so every departure query, and every plan, is the same."""

from __future__ import annotations

import math

import numpy as np
import pytest

from proxplan.planfile import scenario_from_dict
from proxplan.planner.formations import corridor
from proxplan.planner.swarm.departures import LINE_SLACK_M, REACH_SLACK, SHORT_STEPS, DepartureIndex
from proxplan.planner.swarm.keepout import GrownStack
from proxplan.planner.swarm.occupancy import Occupancy
from proxplan.planner.swarm.problem import swarm_problem
from proxplan.planner.swarm.tracks import GRID_DT_S
from proxplan.planner.timing import CORNER_DEVIATION_M
from proxplan.planner.timing.profile import RunMove

from .test_swarm_departures import HORIZON, _line, _random_track


def _reference_rz(st: GrownStack, r2: np.ndarray, dz: np.ndarray, tb: np.ndarray) -> np.ndarray:
    """The pair test as it read before round 27B (two 2-D lookups, the band chosen by nested wheres),
    of squared horizontal distances ``r2`` and heights ``dz``."""
    tb = np.asarray(tb, dtype=np.int64)
    adz = np.abs(dz)
    k = np.minimum(np.floor(adz / st.step_m[tb]).astype(np.int64), st.below2.shape[1] - 1)
    rb2, ra2 = st.below2[tb, k], st.above2[tb, k]
    rc2 = np.where(adz <= st.w_m[tb] + 1e-12, np.maximum(rb2, ra2), np.where(dz < 0, rb2, ra2))
    return (r2 + dz * dz < st.sphere2[tb]) | (r2 < rc2)


def _reference_conflict(st: GrownStack, d: np.ndarray, tb: np.ndarray) -> np.ndarray:
    """:func:`_reference_rz` of relative vectors ``d`` (P, 3), m."""
    return _reference_rz(st, d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1], d[:, 2], tb)


@pytest.fixture(scope="module")
def problem():
    # corridor's three types (Crazyflie, parrot, small quad): tables of three lengths per stack
    return swarm_problem(scenario_from_dict(corridor(12), label="test"))


def _vectors(st: GrownStack, rng, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Relative vectors (m) of random types: uniform in and beyond the tables' reach, and on the
    edges where the answer turns: dz on the tables' rows and on the band |dz| = w, +-0 heights,
    horizontal distances on the tables' radii."""
    n_b, row = st.below2.shape
    tb = rng.integers(0, n_b, n)
    d = np.column_stack([rng.uniform(-0.5, 0.5, n), rng.uniform(-0.5, 0.5, n), rng.uniform(-6.0, 6.0, n)])
    m = n // 4
    d[:m, 2] = rng.choice([-1.0, 1.0], m) * st.step_m[tb[:m]] * rng.integers(0, row + 2, m)  # on a row
    band = st.w_m[tb[m : 2 * m]] + 1e-12  # on the band's edge, and a rounding either side
    edge = np.where(rng.integers(0, 3, m) == 0, band, np.nextafter(band, rng.choice([0.0, 1.0], m)))
    d[m : 2 * m, 2] = rng.choice([-1.0, 1.0], m) * edge
    kb = np.minimum(np.floor(edge / st.step_m[tb[m : 2 * m]]).astype(np.int64), row - 1)
    below, above = st.below2[tb[m : 2 * m], kb], st.above2[tb[m : 2 * m], kb]  # where the band's choice tells
    radius = np.sqrt(rng.uniform(np.minimum(below, above), np.maximum(below, above)))
    d[m : 2 * m, 0], d[m : 2 * m, 1] = radius, 0.0
    d[2 * m : 2 * m + 8, 2] = [0.0, -0.0] * 4
    k = np.minimum(np.floor(np.abs(d[:, 2]) / st.step_m[tb]).astype(np.int64), row - 1)
    on = slice(3 * m, n)  # horizontal distance on the radius of the row read
    radius = np.sqrt(np.where(d[on, 2] < 0, st.below2[tb[on], k[on]], st.above2[tb[on], k[on]]))
    phi = rng.uniform(0.0, 2.0 * np.pi, radius.size)
    d[on, 0], d[on, 1] = radius * np.cos(phi), radius * np.sin(phi)
    return d, tb


@pytest.mark.parametrize("rest", [False, True])
def test_pair_test_in_one_lookup_is_the_table_formula(problem, rest):
    occ = Occupancy(problem, [], HORIZON)
    rng = np.random.default_rng(27 + rest)
    for ta in range(len(set(problem.type_index.tolist()))):
        st = occ.stack(ta, rest)
        assert st.below2.shape[0] == 3
        d, tb = _vectors(st, rng, 20_000)
        want = _reference_conflict(st, d, tb)
        assert 0 < int(want.sum()) < want.size, "the vectors must fall on both sides"
        np.testing.assert_array_equal(st.conflict(d, tb), want)
        r2 = d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1]
        np.testing.assert_array_equal(st.conflict_rz(r2, d[:, 2], tb), want)


def _reference_line_near(ix: DepartureIndex, q_m, reach_m, from_step, until_step, exclude):
    """``_line_near`` as it read before round 27B: the short slice and the long segments scanned apart."""
    K = q_m.shape[0]
    a0, a1 = float(q_m[0, 0]), float(q_m[0, 1])
    e0, e1 = float(q_m[-1, 0]) - a0, float(q_m[-1, 1]) - a1
    length = math.hypot(e0, e1)
    if K < 2 or length <= LINE_SLACK_M:
        return None
    u0, u1 = e0 / length, e1 / length
    dx, dy = q_m[:, 0] - a0, q_m[:, 1] - a1
    s = dx * u0 + dy * u1
    if (s[1:] < s[:-1]).any():
        return None
    r = reach_m * (1.0 + REACH_SLACK) + float(np.abs(dx * u1 - dy * u0).max()) + LINE_SLACK_M
    lasting = ix.t1 - ix.t0 > SHORT_STEPS
    short_rows = np.flatnonzero(~lasting)
    short_rows = short_rows[np.argsort(ix.t0[short_rows], kind="stable")]
    i0, i1 = np.searchsorted(ix.t0[short_rows], [from_step - SHORT_STEPS, until_step + K - 1])
    rows = np.concatenate([short_rows[i0:i1], np.flatnonzero(lasting)])
    xy = ix.P[rows, 0] + 1j * ix.P[rows, 1]
    w = (xy - complex(a0, a1)) * complex(u0, -u1)
    keep = np.abs(w.imag) <= r
    if exclude >= 0:
        keep &= ix.ag[rows] != exclude
    rows, w = rows[keep], w[keep]
    t0, t1 = ix.t0[rows], ix.t1[rows]
    half = np.sqrt(np.maximum(r * r - w.imag * w.imag, 0.0))
    k_lo = np.maximum(np.maximum(t0 - until_step + 1, 0), np.searchsorted(s, w.real - half, side="left"))
    k_hi = np.minimum(np.minimum(t1 - from_step, K), np.searchsorted(s, w.real + half, side="right"))
    n = k_hi - k_lo
    some = n > 0
    rows = rows[some]
    return rows, xy[keep][some], ix.P[rows, 2], t0[some], t1[some], ix.ty[rows], k_lo[some], n[some]


@pytest.mark.parametrize("seed", range(6))
def test_line_near_segments_are_the_two_slice_scan(problem, seed):
    rng = np.random.default_rng(270 + seed)
    me = int(rng.integers(0, problem.n_agents))
    centre = 0.5 * (problem.starts_m[me] + problem.goals_m[me])
    tracks = [_random_track(problem, a, rng, centre) for a in range(problem.n_agents) if a != me]
    if seed % 2:
        tracks.append(_random_track(problem, me, rng, centre))
    occ = Occupancy(problem, tracks, HORIZON)
    ix = occ._departure_index()
    reach = occ._reach_of(int(problem.type_index[me]))
    s, g = problem.starts_m[me], problem.goals_m[me]
    via = centre + np.r_[rng.uniform(-0.6, 0.6, 2), 0.0]
    moves = [
        _line(problem, me, s, g).positions(),
        _line(problem, me, via, via + np.r_[0.3, -0.2, 0.0]).positions(),
        RunMove(np.array([s, via, g]), problem.limits[me], GRID_DT_S, deviation_m=CORNER_DEVIATION_M).positions(),
    ]
    found = 0
    for q in moves:
        for lo, hi in [(0, HORIZON)] + [tuple(sorted(rng.integers(0, HORIZON, 2).tolist())) for _ in range(6)]:
            for exclude in (-1, me):
                got = ix._line_near(q, reach, lo, hi, exclude)
                want = _reference_line_near(ix, q, reach, lo, hi, exclude)
                assert (got is None) == (want is None)
                if got is None:
                    continue
                found += got[0].size
                for a, b in zip(got, want):
                    np.testing.assert_array_equal(a, b)
    assert found > 0, "some segments must lie near the moves"


def _reference_holds(occ: Occupancy, agent: int, w: np.ndarray) -> np.ndarray:
    """``Occupancy._forbidden_holds`` as it read before round 27B: each parked end tested alone."""
    from proxplan.planner.swarm.departures import covered

    T, ta = occ.horizon, int(occ.problem.type_index[agent])
    out = np.zeros(T, dtype=bool)
    P, t0, t1, ty, mv, _ = occ.samples_near(w, w, agent)
    d = P - w[None]
    near = np.flatnonzero((np.abs(d[:, 0]) <= occ.reach) & (np.abs(d[:, 1]) <= occ.reach))
    h = np.zeros(near.size, dtype=bool)
    for rest in (False, True):
        m = mv[near] != rest
        if m.any():
            h[m] = occ.stack(ta, rest).conflict(d[near[m]], ty[near[m]])
    out |= covered(np.minimum(t0[near[h]], T), np.minimum(t1[near[h]], T), T)
    for tr in occ.parked_near(w, w, agent):
        if tr.arrival_step < T and occ.stack(ta, True).conflict((tr.end_m - w)[None], np.array([tr.type]))[0]:
            out[tr.arrival_step :] = True
    return out


@pytest.mark.parametrize("seed", range(4))
def test_holds_with_the_parked_ends_in_one_test_are_the_same(problem, seed):
    rng = np.random.default_rng(2700 + seed)
    me = int(rng.integers(0, problem.n_agents))
    centre = 0.5 * (problem.starts_m[me] + problem.goals_m[me])
    tracks = [_random_track(problem, a, rng, centre) for a in range(problem.n_agents) if a != me]
    occ = Occupancy(problem, tracks, HORIZON)
    parked_hits = 0
    for tr in tracks:  # at every parked end (the test fires there), and around the centre
        for w in (tr.end_m, tr.end_m + np.r_[rng.uniform(-0.3, 0.3, 2), 0.0]):
            got = occ._forbidden_holds(me, int(problem.type_index[me]), np.ascontiguousarray(w, dtype=float))
            np.testing.assert_array_equal(got, _reference_holds(occ, me, w))
            parked_hits += bool(got[-1])
    assert parked_hits > 0, "some holds must be forbidden for good"


def test_holds_forbidden_from_the_earliest_parked_end_in_reach(problem):
    """Two tracks parked for good beside a hold, arriving at different steps: the hold is forbidden
    from the earlier arrival on, as when each end was tested alone."""
    from proxplan.planner.swarm.tracks import GridTrack

    me, a, b = 0, 1, 2
    w = np.array([0.0, 0.0, 1.0])
    tracks = []
    for agent, side, dep in ((a, 1.0, 40), (b, -1.0, 5)):
        end = w + np.r_[0.15 * side, 0.0, 0.0]  # inside the keep-out of a vehicle held at w
        start = end + np.r_[side, 0.0, 0.0]
        tracks.append(
            GridTrack(agent, int(problem.type_index[agent]), start, [(dep, _line(problem, agent, start, end))])
        )
    occ = Occupancy(problem, tracks, HORIZON)
    got = occ._forbidden_holds(me, int(problem.type_index[me]), w)
    np.testing.assert_array_equal(got, _reference_holds(occ, me, w))
    first = min(tr.arrival_step for tr in tracks)
    assert got[first:].all() and first < max(tr.arrival_step for tr in tracks)


def test_swarm_plan_is_the_same_with_the_reference_tests(monkeypatch):
    """A whole swarm plan (corridor-12: prioritised planning, re-timing, makespan repair) with round
    27B's pair test, line scan and holds, then with the references above in their place: the same
    stage and the same tracks, sample for sample."""
    from proxplan.planner.swarm.plan import swarm_timed

    doc = corridor(12)
    runs = []
    for reference in (False, True):
        if reference:
            monkeypatch.setattr(GrownStack, "conflict_rz", _reference_rz)
            monkeypatch.setattr(DepartureIndex, "_line_near", _reference_line_near)
            monkeypatch.setattr(
                Occupancy, "_forbidden_holds", lambda self, agent, ta, w: _reference_holds(self, agent, w)
            )
        runs.append(swarm_timed(scenario_from_dict(doc, label="test")))
    (a, ia), (b, ib) = runs
    assert ia.stage == ib.stage and ia.makespan_s == ib.makespan_s
    assert a.keys() == b.keys()
    for name in a:
        np.testing.assert_array_equal(a[name].knot_t_s, b[name].knot_t_s)
        t = np.arange(0.0, a[name].duration_s + 0.1, 0.01)
        np.testing.assert_array_equal(a[name].sample(t)[0], b[name].sample(t)[0])
