"""The synchronous conflict table's memory (proxplan.planner.swarm.sync.SyncTable, issue 37 round 17A):
one int key per relative motion names that motion alone, and a table bounded to a few verdicts gives
every verdict of an unbounded one (a verdict dropped is computed again, exactly)."""

from __future__ import annotations

import itertools
import random

import numpy as np

from proxplan.planfile import scenario_from_dict
from proxplan.planner.formations import grid_reshuffle
from proxplan.planner.swarm import SyncTable, build_lattice, segment_conflict, swarm_problem
from proxplan.planner.swarm.problem import GROWTH_M


def _lattice_table(max_verdicts: int | None = None):
    problem = swarm_problem(
        scenario_from_dict(grid_reshuffle(9, types=["crazyflie-2.1", "small-quad"]), label="test scenario"),
        tracking_bound=False,
    )
    lat = build_lattice(problem, max_run=2)
    kw = {} if max_verdicts is None else {"max_verdicts": max_verdicts}
    return problem, lat, SyncTable(problem.keepouts, problem.type_index, lat.pos_mm, **kw)


def _queries(problem, lat, count: int, seed: int) -> list[tuple[int, int, int, int, int, int]]:
    """Random steps of two agents: each stays or takes one of its lattice moves, from vertices near
    each other (so that conflicts and clear steps both occur)."""
    rng = random.Random(seed)
    free = [v for v in range(lat.n_grid) if lat.grid_index(v) is not None and lat.free.reshape(-1)[v]]
    out = []
    while len(out) < count:
        i, j = rng.sample(range(problem.n_agents), 2)
        ui = rng.choice(free)
        near = [v for v in free if np.linalg.norm(lat.pos_m[v] - lat.pos_m[ui]) < 1.0]
        uj = rng.choice(near)
        vi = rng.choice(lat.moves(i, ui) + [ui])
        vj = rng.choice(lat.moves(j, uj) + [uj])
        out.append((i, ui, vi, j, uj, vj))
    return out


def test_the_table_equals_the_exact_test_of_each_relative_motion():
    """Every verdict, asked twice (the second from the table), is the exact segment test of the
    relative motion d0 = p(uj) - p(ui) -> d1 = p(vj) - p(vi) for the two agents' types."""
    problem, lat, table = _lattice_table()
    queries = _queries(problem, lat, 600, seed=3)
    seen = {True: 0, False: 0}
    for _ in range(2):
        for i, ui, vi, j, uj, vj in queries:
            rest = ui == vi and uj == vj
            ko = problem.keepouts[(int(problem.type_index[i]), int(problem.type_index[j]))]
            d0 = (lat.pos_mm[uj] - lat.pos_mm[ui]) * 1e-3
            d1 = (lat.pos_mm[vj] - lat.pos_mm[vi]) * 1e-3
            want = segment_conflict(ko, d0, d1, rest=rest, growth_m=GROWTH_M if rest else 0.0)
            got = table.conflict(i, ui, vi, j, uj, vj)
            assert got == want
            seen[got] += 1
    assert seen[True] > 0 and seen[False] > 0  # both verdicts were exercised
    assert table.computed == len(table) <= len(queries)  # the second round came from the table


def test_one_key_per_relative_motion():
    """Keys are equal exactly when the type pair, d0, d1 and both-at-rest are: over every quadruple of
    a handful of vertices spread over the whole lattice (the largest differences included)."""
    problem, lat, table = _lattice_table()
    corners = [int(np.argmin(lat.pos_mm[:, k])) for k in range(3)] + [
        int(np.argmax(lat.pos_mm[:, k])) for k in range(3)
    ]
    verts = sorted(set(corners + [int(v) for v in lat.start_v[:3]]))
    types = sorted({int(t) for t in problem.type_index})
    agent_of = {t: int(np.flatnonzero(problem.type_index == t)[0]) for t in types}
    keys: dict[int, tuple] = {}
    for ti, tj in itertools.product(types, repeat=2):
        i, j = agent_of[ti], agent_of[tj]
        if i == j:
            j = int(np.flatnonzero(problem.type_index == tj)[1])
        for ui, vi, uj, vj in itertools.product(verts, repeat=4):
            P = lat.pos_mm
            name = (ti, tj, *(P[uj] - P[ui]), *(P[vj] - P[vi]), ui == vi and uj == vj)
            key = table._key(i, ui, vi, j, uj, vj)
            assert keys.setdefault(key, name) == name  # a key never stands for two motions
    names = set(keys.values())
    assert len(names) == len(keys)  # nor a motion for two keys


def test_a_bounded_table_gives_every_verdict_of_an_unbounded_one():
    """A table bounded at 64 verdicts drops many and stays within its bound, and answers every query
    as the unbounded table does."""
    problem, lat, full = _lattice_table()
    _, _, small = _lattice_table(max_verdicts=64)
    queries = _queries(problem, lat, 1500, seed=5)
    for q in queries + queries[::-1]:
        assert small.conflict(*q) == full.conflict(*q)
        assert len(small) <= 64
    assert small.dropped > 0 and small.computed > full.computed
    small.clear()
    assert len(small) == 0 and small.conflict(*queries[0]) == full.conflict(*queries[0])
