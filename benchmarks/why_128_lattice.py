"""``why_128.py --lattice`` (round 22B): LaCAM alone on the stage's lattice, its counts and lock-step
makespans (see benchmarks/why_128.py; split by mode in round 28A)."""

from __future__ import annotations

import time
from collections import Counter

import numpy as np


def _stay_fits(problem, sync, pos, C: np.ndarray, a: int, v: int, k: int) -> bool:
    """Whether agent a resting at vertex v during step k (C[k-1] -> C[k]) passes the synchronous test
    against every other agent's move of that step."""
    from proxplan.planner.swarm.lockstep import segment_distance_xy_m

    A = C.shape[1]
    here = np.repeat(pos[v][None], A, axis=0)
    d = segment_distance_xy_m(here, here, pos[C[k - 1]], pos[C[k]])
    near = np.flatnonzero(d < problem.reach_xy_m + 0.05).tolist()
    return all(j == a or not sync.conflict(a, v, v, j, int(C[k - 1, j]), int(C[k, j])) for j in near)


def _loops_cut(problem, sync, pos, C: np.ndarray) -> tuple[int, int]:
    """(loops, vehicles' vertex revisits): loops s1 < s2 of a vehicle (at the same vertex at both, moving
    between) that staying put over s1..s2 would cut (every other move of those steps passing the test)."""
    K, A = C.shape[0] - 1, C.shape[1]
    cut = revisits = 0
    for a in range(A):
        seq = [int(C[0, a])] + [int(C[k, a]) for k in range(1, K + 1) if C[k, a] != C[k - 1, a]]
        revisits += len(seq) - len(set(seq))
        s1 = 0
        while s1 < K:
            v = int(C[s1, a])
            hit = next(
                (
                    s2
                    for s2 in range(K, s1 + 1, -1)
                    if C[s2, a] == v
                    and np.any(C[s1 : s2 + 1, a] != v)
                    and all(_stay_fits(problem, sync, pos, C, a, v, k) for k in range(s1 + 1, s2 + 1))
                ),
                None,
            )
            if hit is None:
                s1 += 1
            else:
                cut += 1
                s1 = hit
    return cut, revisits


def _steps_mergeable(problem, sync, pos, C: np.ndarray) -> int:
    """Pairs of consecutive steps k, k+1 whose configurations C[k-1] -> C[k+1] pass as one straight step:
    every moved segment statically free and every pair within reach passing the synchronous test."""
    from proxplan.planner.swarm.lockstep import _near_pairs

    types = np.asarray(problem.type_index)
    ok = 0
    for k in range(1, C.shape[0] - 1):
        a, b = C[k - 1], C[k + 1]
        moved = np.flatnonzero(a != b).tolist()
        if not all(problem.segment_free(pos[a[i]], pos[b[i]]) for i in moved):
            continue
        pairs = _near_pairs(problem, pos[a], pos[b], types).tolist()
        if all(not sync.conflict(i, int(a[i]), int(b[i]), j, int(a[j]), int(b[j])) for i, j in pairs):
            ok += 1
    return ok


def lattice_counts(args) -> int:
    """LaCAM alone on the stage's lattice, per seed, and what the first-arriving plan does (``--lattice``)."""
    from proxplan.planfile.scenario_load import scenario_from_dict
    from proxplan.planner.formations import LAYOUTS
    from proxplan.planner.sampling.ordering import lower_bound_makespan_s
    from proxplan.planner.swarm import Lacam, SwarmOptions, SyncTable, build_lattice, swarm_problem
    from proxplan.planner.swarm.frozen import unfrozen_problem
    from proxplan.planner.swarm.lockstep import _start_steps, lockstep_tracks

    scenario = scenario_from_dict(LAYOUTS[args.layout](args.n))
    problem, _, _ = unfrozen_problem(swarm_problem(scenario))
    bound = lower_bound_makespan_s(scenario)
    opts = SwarmOptions()
    lat = build_lattice(problem, max_run=opts.max_run)
    print(
        f"{args.layout}-{args.n}: lattice spacing {lat.spacing_m:.2f} m, {lat.shape} grid, {lat.pos_m.shape[0]} vertices, "
        f"reach {problem.reach_xy_m:.2f} m, bound {bound:.2f} s"
    )
    best = None
    for seed in range(args.seeds):
        sync = SyncTable(problem.keepouts, problem.type_index, lat.pos_mm)
        t0 = time.process_time()
        res = Lacam(lat, sync, seed=seed).solve(max_nodes=opts.max_nodes, max_proposals=opts.max_proposals)
        cpu = time.process_time() - t0
        dep = max(tr.arrival_s for tr in lockstep_tracks(lat, res.configurations))
        plain = max(tr.arrival_s for tr in lockstep_tracks(lat, res.configurations, dependencies=False))
        print(
            f"  seed {seed}: {len(res.configurations) - 1} steps, {res.nodes} configurations, {res.proposals} proposals, "
            f"{cpu:.1f} s CPU; lock-step {plain:.2f} s, with dependencies {dep:.2f} s = {dep / bound:.2f}x"
        )
        if best is None or dep < best[0]:
            best = (dep, seed, res, sync)
    assert best is not None
    _, seed, res, sync = best
    C = np.asarray(res.configurations)
    K, A = C.shape[0] - 1, C.shape[1]
    pos, goal, dist = lat.pos_m, lat.goal_v, lat.dist_to_goal
    assert dist is not None
    moves = (C[1:] != C[:-1]).sum(axis=0)
    print(f"\nseed {seed}: moves per vehicle mean {moves.mean():.1f}, max {int(moves.max())} ({K} steps)")
    step_l, agent_l = np.nonzero(C[1:] != C[:-1])
    order = np.argsort(step_l, kind="stable")
    step, agent = step_l[order] + 1, agent_l[order]
    p0, p1 = pos[C[step - 1, agent]], pos[C[step, agent]]
    label, _, _ = _start_steps(problem, step, agent, p0, p1, True)
    print("  step: movers, at goal, moved away from goal, longest / mean move m, dependency groups (largest's movers)")
    for k in range(1, K + 1):
        here = step == k
        lengths = np.linalg.norm(p1[here] - p0[here], axis=1)
        groups = Counter(label[here].tolist())
        d_now = dist[np.arange(A), C[k]]
        d_before = dist[np.arange(A), C[k - 1]]
        print(
            f"  {k:3d}: {int(here.sum()):3d}, {int((C[k] == goal).sum()):3d}, {int((d_now > d_before + 1e-6).sum()):3d}, "
            f"{lengths.max(initial=0.0):.2f} / {lengths.mean() if lengths.size else 0.0:.2f}, {len(groups)} "
            f"({max(groups.values(), default=0)})"
        )
    tracks = lockstep_tracks(lat, res.configurations)
    print("  the latest vehicles:")
    for tr in sorted(tracks, key=lambda tr: -tr.arrival_s)[:5]:
        a = tr.agent
        flown = float(np.linalg.norm(pos[C[1:, a]] - pos[C[:-1, a]], axis=1).sum())
        first = int(np.argmax(C[:, a] == goal[a]))
        line = float(np.linalg.norm(problem.goals_m[a] - problem.starts_m[a]))
        print(
            f"    {problem.names[a]}: arrives {tr.arrival_s:.2f} s, {int(moves[a])} moves, {flown:.2f} m flown for a "
            f"{line:.2f} m line, first at its goal at step {first}"
        )
    cut, revisits = _loops_cut(problem, sync, pos, C)
    print(f"  vertex revisits {revisits}; loops cut by staying put: {cut}")
    print(f"  consecutive steps flyable as one: {_steps_mergeable(problem, sync, pos, C)} of {K - 1}")
    return 0
