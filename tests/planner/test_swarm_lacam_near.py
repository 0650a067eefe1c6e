"""LaCAM asks the synchronous table only about pairs that may come within reach (issue 37, round 18B):
the vectorised pre-test (``sync.maybe_near``) never rules out a pair the exact test finds in conflict,
and the search with it gives the same configurations as the search that asks every neighbour."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.planfile import scenario_from_dict
from proxplan.planner.formations import corridor, grid_reshuffle
from proxplan.planner.swarm import Lacam, SyncTable, build_lattice, swarm_problem
from proxplan.planner.swarm.problem import GROWTH_M
from proxplan.planner.swarm.sync import far_apart, maybe_near, segment_conflict


class _AskEveryNeighbour(Lacam):
    """The search before the pre-test: every neighbour within the move radius is asked."""

    def _near_decided(self, Q, i, cands, decided, to):
        return [[True] * len(decided) for _ in cands]

    def _near_staying(self, Q, i, v, among):
        return among

    def _near_pairs(self, Q, pairs, ends_a, ends_b):
        out = [[] for _ in range(self.A)]
        for a, b in pairs.tolist():
            out[a].append(b)
            out[b].append(a)
        return out


def test_maybe_near_never_rules_out_a_conflict():
    """Random relative segments in whole millimetres, many of them near the reach: where the pre-test
    says "not near", far_apart holds and the exact test finds no conflict, moving or at rest."""
    problem = swarm_problem(scenario_from_dict(grid_reshuffle(16, seed=1), label="test scenario"))
    ko = problem.keepouts[(0, 0)]
    table = SyncTable(problem.keepouts, problem.type_index, np.zeros((1, 3), dtype=np.int64))
    reach = float(table.reach_any_m[0, 0])
    rng = np.random.default_rng(0)
    ruled_out = 0
    for _ in range(3000):
        d0 = rng.uniform(-1.0, 1.0, 3) * rng.choice([0.3, 0.6, 1.5])
        d1 = d0 + rng.uniform(-1.0, 1.0, 3) * rng.choice([0.0, 0.3, 1.0])
        d0_mm, d1_mm = np.round(d0 * 1000.0), np.round(d1 * 1000.0)
        near = bool(maybe_near(d0_mm[:2] * 1e-3, d1_mm[:2] * 1e-3, np.float64(reach)))
        if not near:
            ruled_out += 1
            d_mm = tuple(int(c) for c in d0_mm) + tuple(int(c) for c in d1_mm)
            assert far_apart(d_mm, reach)
            for rest in (False, True):
                assert not segment_conflict(
                    ko, d0_mm * 1e-3, d1_mm * 1e-3, rest=rest, growth_m=GROWTH_M if rest else 0.0
                )
    assert 300 < ruled_out < 2700  # both answers are exercised


@pytest.mark.parametrize("doc", [grid_reshuffle(49, seed=1), corridor(24)], ids=["grid-49", "corridor-24"])
def test_lacam_with_the_pre_test_gives_the_same_configurations(doc):
    """The same seed, the same lattice: the configurations of the search that asks only the pairs that
    may come within reach equal those of the search that asks every neighbour, with fewer queries."""
    problem = swarm_problem(scenario_from_dict(doc, label="test scenario"))
    lat = build_lattice(problem)
    got = []
    for cls in (Lacam, _AskEveryNeighbour):
        table = SyncTable(problem.keepouts, problem.type_index, lat.pos_mm)
        result = cls(lat, table, seed=3).solve(max_nodes=2000)
        got.append((result.configurations, table.computed))
    assert got[0][0] == got[1][0]
    assert len(got[0][0]) > 2
    assert got[0][1] < got[1][1]
