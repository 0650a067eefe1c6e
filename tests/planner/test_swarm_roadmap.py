"""Shared swarm roadmap (proxplan.planner.swarm: roadmap, search, pbs, plan): conflict sets
against a scalar brute force, PBS solving what prioritised planning cannot, determinism, verify."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from proxplan.planfile import scenario_from_dict
from proxplan.planner.checks.constraints import CutoffTable, cutoff_table
from proxplan.planner.formations import circle_swap, grid_reshuffle
from proxplan.planner.pipeline import plan_roadmap
from proxplan.planner.swarm import Search, pbs, prioritized
from proxplan.planner.swarm.plan import build, search_plan
from proxplan.planner.swarm.roadmap import SAMPLE_M
from proxplan.verify import verify_plan

CF = ["crazyflie-2.1"]
MIXED = ["crazyflie-2.1", "small-quad"]


def _scalar_conflict(pa, pb, va, vb, limits, w: float) -> bool:
    """Brute force, scalar: any sample point of a and of b within separation + w, or inside the
    cut-off of whichever is above grown by w (largest over dz +- w, plus w; both ways near dz = 0)."""
    lvl, rule = limits.authority_fraction, limits.invalid_zone_rule
    ab: CutoffTable = cutoff_table(va, vb, level=lvl, rule=rule)
    ba: CutoffTable = cutoff_table(vb, va, level=lvl, rule=rule)
    sep = max(limits.min_separation_m, va.body_radius_m + vb.body_radius_m) + w

    def grown(t: CutoffTable, dz: float) -> float:
        vals = [t.lookup(z) for z in np.linspace(max(dz - w, 1e-4), dz + w, 41)]
        rc = max(vals)
        return rc + w if rc > 0 else 0.0

    for p in pa:
        for q in pb:
            d = q - p
            r = float(np.hypot(d[0], d[1]))
            dz = float(d[2])
            if float(np.linalg.norm(d)) < sep:
                return True
            if dz < -w and r < grown(ab, -dz):
                return True
            if dz > w and r < grown(ba, dz):
                return True
            if abs(dz) <= w and r < max(grown(ab, abs(dz)), grown(ba, abs(dz))):
                return True
    return False


def test_conflict_sets_agree_with_a_scalar_brute_force_on_a_tiny_roadmap():
    sc = scenario_from_dict(grid_reshuffle(4, types=MIXED))
    rm, agents, _ = build(sc)
    types = {a.type_index: sc.vehicles[a.name].vehicle for a in agents}
    w = sc.limits.tracking_margin_m + SAMPLE_M
    ok = np.concatenate([rm.vertex_ok.reshape(-1)] + [rm.edge_ok[a].reshape(-1) for a in range(3)])
    atoms = np.concatenate([np.flatnonzero(ok), np.arange(rm.n_lattice_atoms, rm.n_atoms)])
    rng = np.random.default_rng(1)
    n_end = len(rm.endpoints_m)
    checked = hits = 0
    for (ta, tb), mat in rm.conflicts.items():
        dense = mat.toarray()
        # every conflicting pair of a few rows plus random pairs
        rows = rng.choice(atoms, size=12, replace=False)
        pairs = [(a, b) for a in rows for b in np.flatnonzero(dense[a])[:15]]
        pairs += [tuple(x) for x in rng.choice(atoms, size=(150, 2))]
        for a, b in pairs:
            rest = (rm.n_lattice_atoms <= a < rm.n_lattice_atoms + n_end) and (
                rm.n_lattice_atoms <= b < rm.n_lattice_atoms + n_end
            )
            want = _scalar_conflict(
                rm.atom_points(a), rm.atom_points(b), types[ta], types[tb], sc.limits, 0.0 if rest else w
            )
            assert bool(dense[a, b]) == want, (ta, tb, a, b)
            checked += 1
            hits += want
    assert hits > 20 and checked - hits > 100  # both verdicts are exercised


def test_conflict_sets_are_symmetric_between_ordered_type_pairs():
    sc = scenario_from_dict(grid_reshuffle(4, types=MIXED))
    rm, _, _ = build(sc)
    for ta, tb in itertools.product(range(len(rm.type_names)), repeat=2):
        diff = rm.conflicts[(ta, tb)] != rm.conflicts[(tb, ta)].T
        assert diff.nnz == 0


def _all_pairs_free(search: Search, paths) -> bool:
    return all(search.first_conflict(p, q) is None for p, q in itertools.combinations(paths, 2))


@pytest.mark.parametrize("doc", [grid_reshuffle(4, types=CF), circle_swap(6, types=CF)], ids=["rotation-4", "circle-6"])
def test_pbs_solves_swaps_where_prioritised_planning_deadlocks(doc):
    sc = scenario_from_dict(doc)
    rm, agents, window = build(sc)
    horizon = 300
    pp = prioritized(Search(rm, agents, window), horizon, restarts=4)
    assert pp.paths is None  # every fixed order tried blocks a vehicle for good
    search = Search(rm, agents, window)
    res = pbs(search, horizon)
    assert res.paths is not None, res.message
    assert _all_pairs_free(search, res.paths)
    plan = plan_roadmap(sc)
    assert verify_plan(plan, sc) == []
    info = plan.metrics["roadmap"]
    end_s = info["makespan_over_lower_bound"] * info["lower_bound_s"]  # last arrival, s
    assert info["lower_bound_s"] <= end_s and info["roadmap_lower_bound_s"] <= end_s + 1e-6  # bounds hold


def test_same_input_same_plan():
    sc = scenario_from_dict(circle_swap(6, types=CF))
    a = plan_roadmap(sc)
    b = plan_roadmap(sc)
    for name in a.vehicles:
        assert np.array_equal(a.vehicles[name].position_m, b.vehicles[name].position_m)
    _, r1, _ = search_plan(sc)
    _, r2, _ = search_plan(sc)
    assert r1.high_level_nodes == r2.high_level_nodes and r1.expansions == r2.expansions


def test_docking_scenarios_fall_back_to_the_sampling_planner():
    from proxplan.planfile import load_scenario
    from proxplan.planner import plan_scenario
    from tests.conftest import SCENARIOS

    sc = load_scenario(SCENARIOS / "handoff.yaml")
    plan = plan_scenario(sc, method="roadmap")
    assert plan.method == "sampling"
    assert any(n.startswith("roadmap: not used") for n in plan.notes)


def test_a_hovering_vehicle_off_the_lattice_stays_put():
    doc = circle_swap(6, types=CF)
    doc["vehicles"]["keeper"] = {"type": "crazyflie-2.1", "start": [0.13, 2.07, 2.4], "hover": True}
    sc = scenario_from_dict(doc)
    plan = plan_roadmap(sc)
    keeper = plan.vehicles["keeper"].position_m
    assert np.abs(keeper - np.array([0.13, 2.07, 2.4])).max() < 1e-9
    assert verify_plan(plan, sc) == []
