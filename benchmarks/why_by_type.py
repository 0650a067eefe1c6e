"""What sets the makespan of interchangeable vehicles (``assign_goals: by_type``), in-process (issue 37
item 5; docs/planner.md, "Stop 53, round 15B").

For each named layout of ``benchmarks/bench_swarm.py`` at N vehicles: the assignment and its bound B
(s), the synchronised straight step's conflicting pairs (``swarm.straight.straight_step_conflicts``),
the swarm layer's plan (``swarm_timed``) and, among the vehicles arriving after 1.3 B, how many are in
a straight-step conflict, fly a route of more than one move (a detour) and leave late. Then the
certified single-vehicle bound round the obstacles under the assignment (does B route round them?) and
the lines through an obstacle each flown alone round it (``yielding.around_obstacle``; round 24S), and what the
stages giving way (``SwarmInfo.yielding``) and prioritised planning gave or gave up on (round 25S); the passing
stage's latest group's arcs, each timed against its path's speed-and-acceleration floor
(``timing.path_law.speed_accel_floor_s``; round 27S). Then the
detour estimate of the worst conflicting pair: for each pair, the cheaper of the two vehicles' two-leg
rest-to-rest detours through a corner ``reach_xy_m`` aside at mid-line (jerk-limited rest-to-rest
time of each leg, ``timing.profile.rest_to_rest``), the largest over the pairs, over B. With
``--milp K [K ...]``: the fewest conflicting pairs of any assignment whose lines take at most K x B
(every line of a type to every goal of it within that time a binary variable, one goal each, one
vehicle per goal, a variable per conflicting pair of candidate lines, exact pair test
``swarm.sync.segment_conflict``; ``scipy.optimize.milp``, HiGHS, ``--milp-time`` s each; first whether an assignment without any
conflicting pair exists (all pair variables fixed at 0), then the count: "optimal",
"infeasible" (no assignment at all), or the best found and HiGHS' proven lower bound when the limit stops it).

    cd /tmp && python /path/to/benchmarks/why_by_type.py --layout grid circle corridor pillar --n 64 --milp 1.0 1.3
"""

from __future__ import annotations

import argparse
import math
import sys
import time

import numpy as np


def _detour_s(length_m: float, aside_m: float, limits) -> float:
    """Two rest-to-rest legs through a corner ``aside_m`` beside the middle of a line of ``length_m``, s."""
    from proxplan.planner.swarm.tracks import GRID_DT_S
    from proxplan.planner.timing.profile import rest_to_rest

    return 2.0 * rest_to_rest(math.hypot(0.5 * length_m, aside_m), limits, GRID_DT_S).duration_s


def _round_obstacles(scenario, problem, conflicts, bound_s: float) -> str:
    """Whether the assignment's bound routes round the obstacles: the largest certified single-vehicle bound
    under the assignment (``bounds.vehicle_bound_s``: through the free windows of each obstacle's planes)
    over B, and the lines through an obstacle each flown alone round it (``yielding.around_obstacle``, timed
    by ``chain.time_chain`` through the corner against nobody; and on its smallest free arc round it,
    ``yielding.round_arc_bulges`` timed by ``arc_timing.time_arc``, round 29S), the slowest over B."""
    from proxplan.planner.bounds import vehicle_bound_s
    from proxplan.planner.swarm.arc_timing import time_arc
    from proxplan.planner.swarm.chain import time_chain
    from proxplan.planner.swarm.occupancy import Occupancy
    from proxplan.planner.swarm.prioritised_stage import horizon_steps
    from proxplan.planner.swarm.yielding import around_obstacle, round_arc_bulges

    cache: dict = {}
    certified = max(vehicle_bound_s(scenario, name, cache)[0] for name in problem.names)
    through = sorted({i for i, j in conflicts if i == j})
    occ = Occupancy(problem, [], horizon_steps(bound_s))
    alone, arcs = [], []
    for a in through:
        times = [time_chain(occ, a, chain, through=True) for chain in around_obstacle(problem, a)]
        alone.append(min((t.track.arrival_s for t in times if t is not None), default=math.inf))
        got = [time_arc(occ, a, bulge) for bulge in round_arc_bulges(problem, a)]
        arcs.append(min((t.track.arrival_s for t in got if t is not None), default=math.inf))
    slowest = f"{max(alone) / bound_s:.2f} B, on its arc {max(arcs) / bound_s:.2f} B" if alone else "-"
    return (
        f"certified bound round the obstacles {certified:.3f} s = {certified / bound_s:.3f} B; {len(through)} lines "
        f"through an obstacle ({', '.join(problem.names[a] for a in through) or '-'}), the slowest flown alone "
        f"round it {slowest}; {_forced_across(scenario)}"
    )


def _forced_across(scenario) -> str:
    """Per obstacle's extent along x or y (``bounds.slabs``) and type, how many vehicles every assignment
    sends across it: the difference between the type's starts and the goals listed for it below the extent
    (the assignment keeps types; each crossing vehicle changes the count by one; round 29S)."""
    from proxplan.planner.bounds import slabs

    tasks = [t for t in scenario.vehicles.values() if t.goal_m is not None and not t.hover and t.dock_with is None]
    out: list[str] = []
    seen = set()
    for slab in slabs(scenario):
        k = slab.axis
        if (k, slab.lo_m, slab.hi_m) in seen:  # two boxes with one extent (corridor's walls)
            continue
        seen.add((k, slab.lo_m, slab.hi_m))
        for name in sorted({t.type_name for t in tasks}):
            own = [t for t in tasks if t.type_name == name]
            diff = sum(t.start_m[k] < slab.lo_m for t in own) - sum(t.goal_m[k] < slab.lo_m for t in own)
            if diff:
                way = "+" if diff > 0 else "-"
                out.append(f"{abs(diff)} {name} towards {way}{'xy'[k]} across [{slab.lo_m:g}, {slab.hi_m:g}]")
    return "forced across: " + ("; ".join(out) if out else "none")


def _passing_detail(problem, conflicts, bound_s: float) -> str:
    """What the passing stage (``passes.passing_stage``, no arrival bound) does with the conflicting lines:
    the components without a conflict-free joint move (their sizes: their members are timed one by one),
    and in its plan (horizon as the pipeline's, from ``bound_s``, s) the latest vehicle, how long it waits at its start, its component and the vehicles
    whose tracks its component's shortest joint move meets when departing at once (round 26S)."""
    from proxplan.planner.swarm.occupancy import Occupancy
    from proxplan.planner.swarm.pass_moves import conflict_components, fitted, joint_moves
    from proxplan.planner.swarm.passes import passing_stage
    from proxplan.planner.swarm.prioritised_stage import horizon_steps
    from proxplan.planner.swarm.tracks import GRID_DT_S

    comps = conflict_components([(i, j) for i, j in conflicts if i != j])
    free = {
        c: [f for f in (fitted(problem, jm) for jm in joint_moves(problem, c, checked=False)) if f is not None]
        for c in comps
    }
    sizes = sorted((len(c) for c in comps if not free[c]), reverse=True)
    head = f"{len(comps)} components, {len(sizes)} without a joint move (sizes {sizes})"
    got = passing_stage(problem, horizon_steps(bound_s), conflicts)
    if got.stage is None:
        return f"{head}; unbounded: {got.note}"
    tracks = {tr.agent: tr for tr in got.stage.tracks}
    late = max(tracks.values(), key=lambda tr: (tr.arrival_step, -tr.agent))
    wait = late.moves[0][0] if late.moves else 0
    comp = next((c for c in comps if late.agent in c), None)
    names = problem.names
    if comp is None or not free[comp]:
        return f"{head}; unbounded: latest {names[late.agent]} timed one by one, waits {wait * GRID_DT_S:.2f} s"
    occ = Occupancy(problem, [tr for a, tr in tracks.items() if a not in comp], late.arrival_step + 2)
    shortest = min(free[comp], key=lambda jm: jm.steps)
    hem = sorted({b for tr in shortest.tracks(problem, 0) for b in occ.conflicting_agents(tr)})
    return (
        f"{head}; unbounded: latest {names[late.agent]} ({'+'.join(names[a] for a in comp)}, shortest joint move "
        f"{shortest.steps * GRID_DT_S:.2f} s, '{shortest.label}') departs after {wait * GRID_DT_S:.2f} s; "
        f"departing at once it meets {', '.join(names[b] for b in hem) or 'nobody'}; {_arc_gaps(problem, shortest)}"
    )


def _arc_gaps(problem, jm) -> str:
    """Each arc of the joint move ``jm``: its time (s, its law, ``timing.path_law``) against the speed-and-
    acceleration floor of its path (``path_law.speed_accel_floor_s``, a lower bound; round 27S)."""
    from proxplan.planner.timing.arcs import ArcMove
    from proxplan.planner.timing.path_law import speed_accel_floor_s

    out = []
    for a, legs in zip(jm.members, jm.moves):
        for _, mv in legs:
            if isinstance(mv, ArcMove):
                floor = speed_accel_floor_s(mv.delta, mv.bulge, problem.limits[a])
                out.append(f"{problem.names[a]} arc {mv.duration:.3f} s (floor {floor:.3f} s)")
    return "; ".join(out) or "no arc"


def _fewest_conflicts(problem, bound_s: float, time_limit_s: float) -> str:
    """The MILP of the module on ``problem`` with lines of at most ``bound_s``: its verdict."""
    from scipy.optimize import Bounds, LinearConstraint, milp
    from scipy.sparse import coo_matrix
    from scipy.spatial import cKDTree

    from proxplan.planner.swarm.problem import GROWTH_M
    from proxplan.planner.swarm.sync import segment_conflict
    from proxplan.planner.timing.durations import duration_table

    S, G, ty = problem.starts_m, problem.goals_m, problem.type_index
    n = problem.n_agents
    cand = [
        (i, g)
        for i in range(n)
        for g in range(n)
        if ty[i] == ty[g]
        and duration_table(problem.limits[i]).duration_s(float(np.linalg.norm(G[g] - S[i]))) <= bound_s + 1e-9
    ]
    ci = np.array([c[0] for c in cand])
    cg = np.array([c[1] for c in cand])
    p0, p1 = S[ci], G[cg]
    mid = 0.5 * (p0 + p1)[:, :2]
    half = 0.5 * np.linalg.norm((p1 - p0)[:, :2], axis=1)
    reach = problem.reach_xy_m
    conflicts = []
    for a, b in cKDTree(mid).query_pairs(2.0 * float(half.max()) + reach, output_type="ndarray").tolist():
        if ci[a] == ci[b] or cg[a] == cg[b] or np.linalg.norm(mid[a] - mid[b]) > half[a] + half[b] + reach:
            continue
        rest = bool(np.allclose(p0[a], p1[a]) and np.allclose(p0[b], p1[b]))
        ko = problem.keepouts[(int(ty[ci[a]]), int(ty[ci[b]]))]
        if segment_conflict(ko, p0[b] - p0[a], p1[b] - p1[a], rest=rest, growth_m=GROWTH_M if rest else 0.0):
            conflicts.append((a, b))
    m, c = len(cand), len(conflicts)
    rows, cols, vals, lo, hi = [], [], [], [], []
    for r, (key, idx) in enumerate([(k, ci) for k in range(n)] + [(k, cg) for k in range(n)]):
        for j in np.flatnonzero(idx == key):
            rows.append(r)
            cols.append(int(j))
            vals.append(1.0)
        lo.append(1.0)
        hi.append(1.0)
    for q, (a, b) in enumerate(conflicts):  # x_a + x_b - y_q <= 1
        r = 2 * n + q
        rows += [r, r, r]
        cols += [a, b, m + q]
        vals += [1.0, 1.0, -1.0]
        lo.append(-np.inf)
        hi.append(1.0)
    A = coo_matrix((vals, (rows, cols)), shape=(2 * n + c, m + c)).tocsr()
    # first: is there an assignment with no conflicting pair at all (every y_q = 0)?
    free = milp(
        np.zeros(m + c),
        constraints=LinearConstraint(A, lo, hi),
        integrality=np.ones(m + c),
        bounds=Bounds(0, np.r_[np.ones(m), np.zeros(c)]),
        options={"time_limit": time_limit_s},
    )
    if free.status == 0:
        return f"{m} candidate lines: an assignment without a conflicting pair exists"
    none = "none without a conflicting pair (infeasible); " if free.status == 2 else ""
    res = milp(
        np.r_[np.zeros(m), np.ones(c)],
        constraints=LinearConstraint(A, lo, hi),
        integrality=np.ones(m + c),
        bounds=Bounds(0, 1),
        options={"time_limit": time_limit_s},
    )
    if res.status == 2:
        return f"{m} candidate lines: no assignment at all (infeasible)"
    if res.x is None:
        return f"{m} candidate lines: {none}none found in {time_limit_s:g} s"
    got = int(round(float(res.x[m:].sum())))
    bound = getattr(res, "mip_dual_bound", None)  # HiGHS' proven lower bound on the count
    least = max(math.ceil(float(bound) - 1e-6) if bound is not None else 0, 1 if free.status == 2 else 0)
    proven = "" if res.status == 0 else f" (at least {least}, proven)"
    verdict = f"{'optimal' if res.status == 0 else 'best found'} {got}{proven}"
    return f"{m} candidate lines, {c} conflicting pairs of them: {none}{verdict}"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--layout", nargs="+", default=["grid", "circle", "corridor", "pillar"])
    ap.add_argument("--n", type=int, default=64)
    ap.add_argument("--milp", type=float, nargs="*", default=[], help="line-time factors K (x B) for the MILP")
    ap.add_argument("--milp-time", type=float, default=60.0, help="HiGHS time limit per MILP, s")
    args = ap.parse_args()

    from proxplan.planfile import scenario_from_dict
    from proxplan.planner.formations import layout_doc
    from proxplan.planner.swarm.goals import apply_assignment
    from proxplan.planner.swarm.options import SwarmOptions
    from proxplan.planner.swarm.plan import swarm_timed
    from proxplan.planner.swarm.problem import swarm_problem
    from proxplan.planner.swarm.straight import straight_step_conflicts

    for layout in args.layout:
        scenario, record = apply_assignment(scenario_from_dict(layout_doc(layout, args.n, assign="by_type")))
        assert record is not None
        bound = float(record["lower_bound_s"])
        problem = swarm_problem(scenario)
        conflicts = straight_step_conflicts(problem)
        in_conflict = {a for pair in conflicts for a in pair}
        t0 = time.process_time()
        # by type the pipeline leaves reserve_starts off (SwarmOptions); called directly, None means on
        paths, info = swarm_timed(scenario, SwarmOptions(reserve_starts=False))
        cpu = time.process_time() - t0
        late = []
        for a, name in enumerate(problem.names):
            path = paths[name]
            if path.duration_s > 1.3 * bound + 1e-9:
                moves = sum(1 for s in path.segments if s is not None)
                left = float(path.knot_t_s[1]) if path.segments and path.segments[0] is None else 0.0
                late.append((a in in_conflict, moves > 1, left > 0.05))
        length = np.linalg.norm(problem.goals_m - problem.starts_m, axis=1)
        worst = max(
            (
                min(_detour_s(float(length[k]), problem.reach_xy_m, problem.limits[k]) for k in (i, j))
                for i, j in conflicts
                if i != j
            ),
            default=0.0,
        )
        print(f"{layout}-{args.n} by_type: {_round_obstacles(scenario, problem, conflicts, bound)}", flush=True)
        print(
            f"{layout}-{args.n} by_type: B {bound:.3f} s; {len(conflicts)} straight-step conflicts "
            f"({sum(1 for i, j in conflicts if i == j)} lines through an obstacle); plan ({info.stage}) "
            f"{info.makespan_s:.2f} s = {info.makespan_s / bound:.2f} B, {cpu:.1f} s CPU; after 1.3 B: {len(late)}, "
            f"in a conflict {sum(x[0] for x in late)}, detoured {sum(x[1] for x in late)}, left late "
            f"{sum(x[2] for x in late)}; worst pair's cheaper detour {worst / bound:.2f} B",
            flush=True,
        )
        # what the stages giving way and prioritised planning gave or gave up on (round 25S)
        print(f"    giving way: {info.yielding}\n    prioritised: {info.prioritised}", flush=True)
        print(f"    passing stage: {_passing_detail(problem, conflicts, bound)}", flush=True)
        for k in args.milp:
            t1 = time.process_time()
            verdict = _fewest_conflicts(problem, k * bound, args.milp_time)
            print(f"    fewest conflicting pairs, lines <= {k:g} B: {verdict} ({time.process_time() - t1:.1f} s CPU)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
