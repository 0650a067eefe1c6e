"""What vehicles are to each other in the swarm layer (proxplan.planner.swarm.sync, keepout): the
synchronous table equals a dense relative-motion check, the horizontal reach rules out only what
the exact test clears, following is allowed and a head-on swap is not, and predicted deflections
grow the keep-out."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.planfile import scenario_from_dict
from proxplan.planner.formations import corridor, grid_reshuffle
from proxplan.planner.swarm import SyncTable, build_lattice, segment_conflict, swarm_problem
from proxplan.planner.swarm.problem import GROWTH_M


def _brute(ko, d0, d1, rest: bool, grow_m: float = 0.0) -> bool:
    """Dense sampling of the relative segment against the keep-out (KeepOut.conflict itself)."""
    s = np.linspace(0.0, 1.0, 4001)[:, None]
    d = d0 * (1.0 - s) + d1 * s
    if grow_m > 0.0:  # the keep-out grown: shrink every vector towards the pair by grow_m
        r = np.linalg.norm(d[:, :2], axis=1)
        shrink = np.where(r > grow_m, (r - grow_m) / np.maximum(r, 1e-12), 0.0)
        d = d * np.column_stack([shrink, shrink, np.ones_like(shrink)])
        n = np.linalg.norm(d0 * (1.0 - s) + d1 * s, axis=1)
        sep = ko.separation_m + (ko.w_rest_m if rest else ko.w_move_m) + grow_m
        if bool((n < sep).any()):
            return True
    return bool(ko.conflict(d, rest=rest).any())


def test_synchronous_table_equals_a_brute_force_relative_motion_check():
    """On a tiny two-level lattice with two vehicle types, every pair of moves (both agents: stay
    or one of the lattice's moves) gets the table's verdict equal to a dense relative-motion check:
    the table never misses a conflict, and where only the table sees one the segment grazes the
    keep-out (the brute force finds it with the keep-out grown by 1 mm)."""
    doc = {
        "name": "tiny",
        "workspace": {"min": [-1.5, -1.5, 0.0], "max": [1.5, 1.5, 3.0]},
        "limits": {"authority_fraction": 0.1, "min_separation_m": 0.25},
        "vehicles": {
            "a": {"type": "crazyflie-2.1", "start": [0.0, 0.0, 1.0], "goal": [0.6, 0.0, 1.5]},
            "b": {"type": "small-quad", "start": [0.6, 0.6, 1.5], "goal": [0.0, 0.6, 1.0]},
        },
    }
    problem = swarm_problem(scenario_from_dict(doc, label="test scenario"))
    lat = build_lattice(problem, max_run=2)
    table = SyncTable(problem.keepouts, problem.type_index, lat.pos_mm)
    centre = int(lat.start_v[0])
    moves_a = lat.moves(0, centre) + [centre]
    grid_b = [v for v in range(lat.n_grid) if lat.grid_index(v) is not None and lat.free.reshape(-1)[v]]
    grid_b = [v for v in grid_b if np.linalg.norm(lat.pos_m[v, :2] - lat.pos_m[centre, :2]) < 1.0]
    checked = agree = 0
    for ub in grid_b:
        for vb in lat.moves(1, ub)[:6] + [ub]:
            for va in moves_a:
                got = table.conflict(0, centre, va, 1, ub, vb)
                rest = va == centre and vb == ub
                ko = problem.keepouts[(int(problem.type_index[0]), int(problem.type_index[1]))]
                d0 = (lat.pos_mm[ub] - lat.pos_mm[centre]) * 1e-3
                d1 = (lat.pos_mm[vb] - lat.pos_mm[va]) * 1e-3
                grow = GROWTH_M if rest else 0.0
                want = _brute(ko, d0, d1, rest, grow)
                checked += 1
                if got == want:
                    agree += 1
                    continue
                assert got and not want, f"table misses a conflict: {d0} -> {d1} (rest={rest})"
                assert _brute(ko, d0, d1, rest, grow + 1e-3), f"table-only conflict is not a graze: {d0} -> {d1}"
    assert checked > 500
    assert agree >= 0.98 * checked


def test_a_relative_move_the_horizontal_reach_rules_out_never_conflicts():
    """``sync.far_apart`` settles a synchronous test without the exact one only where the exact test
    (``segment_conflict``) finds no conflict: random relative moves of every type pair, moving and at
    rest, many of them grazing the reach (d0 and d1 drawn around it), whole millimetres as in the table."""
    from proxplan.planner.swarm.sync import far_apart

    problem = swarm_problem(scenario_from_dict(corridor(6), label="test scenario"))
    rng = np.random.default_rng(0)
    ruled_out = conflicts = 0
    for ko in problem.keepouts.values():
        for rest in (False, True):
            grow = GROWTH_M if rest else 0.0
            reach = ko.horizontal_reach_m(rest=rest) + grow
            for _ in range(400):
                r = reach * rng.uniform(0.6, 1.6, 2)
                ang = rng.uniform(0.0, 2.0 * np.pi, 2)
                dz = rng.uniform(-1.5, 1.5, 2)
                d = np.column_stack([r * np.cos(ang), r * np.sin(ang), dz])
                d_mm = tuple(int(v) for v in np.round(d.reshape(-1) * 1e3))
                exact = segment_conflict(
                    ko, np.array(d_mm[:3]) * 1e-3, np.array(d_mm[3:]) * 1e-3, rest=rest, growth_m=grow
                )
                conflicts += exact
                if far_apart(d_mm, reach):
                    ruled_out += 1
                    assert not exact, f"ruled out, but the exact test finds a conflict: {d_mm} (rest={rest})"
    assert ruled_out > 100 and conflicts > 100  # both kinds occur


def test_following_is_allowed_and_a_head_on_swap_is_not():
    """Synchronous semantics: a vehicle may move into the place another leaves in the same step
    (following), two vehicles may not swap places head-on."""
    doc = {
        "name": "line",
        "workspace": {"min": [-2.0, -1.0, 0.0], "max": [2.0, 1.0, 3.0]},
        "limits": {"authority_fraction": 0.1, "min_separation_m": 0.25},
        "vehicles": {
            "a": {"type": "crazyflie-2.1", "start": [0.0, 0.0, 1.0], "goal": [0.9, 0.0, 1.0]},
            "b": {"type": "crazyflie-2.1", "start": [-0.9, 0.0, 1.0], "goal": [0.0, 0.0, 1.0]},
        },
    }
    problem = swarm_problem(scenario_from_dict(doc, label="test scenario"))
    lat = build_lattice(problem, max_run=3)
    table = SyncTable(problem.keepouts, problem.type_index, lat.pos_mm)
    a0, a1 = int(lat.start_v[0]), int(lat.goal_v[0])
    b0 = int(lat.start_v[1])
    assert not table.conflict(0, a0, a1, 1, b0, a0)  # b follows a into a's place
    assert table.conflict(0, a0, b0, 1, b0, a0)  # swap head-on


def test_predicted_deflections_grow_the_keepout_moving_and_at_rest():
    doc = grid_reshuffle(4, types=["crazyflie-2.1"])
    plain = swarm_problem(scenario_from_dict(doc, label="test scenario"), tracking_bound=False)
    sc = scenario_from_dict(doc, label="test scenario")
    grown = swarm_problem(sc, deflection_m={n: 0.015 for n in sc.vehicles}, tracking_bound=False)  # a pair: 3 cm
    ko, kg = plain.keepouts[(0, 0)], grown.keepouts[(0, 0)]
    for rest in (True, False):
        w = ko.w_rest_m if rest else ko.w_move_m
        edge = ko.separation_m + w + 0.015  # outside the plain keep-out, inside the one grown by 3 cm
        d = np.array([[edge, 0.0, 0.0]])
        assert not ko.conflict(d, rest=rest)[0] and kg.conflict(d, rest=rest)[0]
        far = np.array([[edge + 0.03, 0.0, 0.0]])
        assert not kg.conflict(far, rest=rest)[0]
    assert grown.reach_xy_m == pytest.approx(plain.reach_xy_m + 0.03)
