"""Why a 128-vehicle plan of the swarm layer is long (issue 37, round 20B): which stage gives it, why
prioritised planning gave up, and what sets the makespan of the plan kept.

Runs ``swarm_timed`` in this process on a named layout with the options the pipeline uses for fixed
goals (one worker, reserved starts) and prints:

* every pass of prioritised planning (the whole swarm's and each stacked level's): its vehicles, hold,
  plannings made, vehicles planned when it gave up, how it gave up, the vehicles that failed and how
  often, and how many times a vehicle had to be planned past reserved starts (start-trapped);
* CPU at the first progress message of each stage (where the time goes);
* the plan kept: its stage, makespan against the bound, and the latest vehicle of the tracks before
  re-timing: its moves, the time it flies and the time it waits, against its own straight line.

With ``--one-pass`` (round 21B) it runs instead one pass of prioritised planning of the whole swarm in
the dependency order with the stage's options (reserved starts, hold ``--hold-s``, the stage's repair,
planning and in-collision counts) and prints how it ended: plannings, CPU, vehicles still queued when it
gave up, vehicles planned through a holding point (``--holding``: ``PriorityOptions.holding``, swarm.holding),
and how many ordered pairs (a, b) have a's start AND goal within keep-out of b's track flown alone (a must
leave before b passes and arrive after it). ``--whole-box``: the wavefront searches the whole free box
when the start-goal box grown by ``MARGIN_M`` holds no route (not only where the straight line crosses a
wall; a diagnosis, monkeypatched here).

With ``--lattice`` (round 22B) it runs instead LaCAM alone on the stage's lattice for ``--seeds`` seeds
(each with the whole count budget, so the plans of the stage's seeds while the first search finishes)
and prints per seed the lattice's own counts (steps, configurations, proposals, CPU) and the lock-step
makespan with and without the dependency execution; then, for the first-arriving seed: moves per vehicle
and vertices revisited, per step the movers, the vehicles at their goals, the vehicles moved away from
their goals, the step's longest and mean move and its dependency groups (lockstep; the largest one's
movers); the latest vehicles
(moves, metres flown, the first step at their goals); how many loops of a vehicle (leaving a vertex and
coming back) could be cut by staying there against everyone else's moves, and how many pairs of
consecutive steps could be flown as one straight step (every pair passing the synchronous test).

The default mode also prints (round 23B) the latest vehicles of the FINAL tracks (re-timed and repaired):
each rest of 0.25 s or more (at the start, at the goal or aside, from when) and from when the vehicle's goal
is clear of every other track for good (a vehicle resting at its start until then waits for the stream to
pass its goal).

With ``--flow`` (round 23B) it measures what streams in lanes could give: the vehicles grouped by direction of
travel (``direction_groups``), each group planned alone by the swarm layer (no other group in its way: what
lanes that separate the groups completely would give at best), the lane routes (``lane_routes``: the middle
leg offset sideways and in height by ``FLOW_LATERAL_REACHES`` x ``FLOW_DZ_M``, the offset whose flight passes
the fewest other starts and goals kept) and how many other starts and goals the best route of each vehicle
still passes, and the flow timing along them (``flow_timing``: each vehicle after those whose starts its route
passes and before those whose goals it passes, ties the longest flight first; exact timing one vehicle after
another, the others' starts reserved; started again at most ``FLOW_RESTARTS`` times with the vehicle that could
not be timed first), with its latest vehicles' rests where it times every vehicle.

With ``--level K`` (round 26B) it plans instead level K of the stacked plan (bottom first) alone by
prioritised planning with the level options (``plan._level_options``; ``--level-options`` JSON changes them,
e.g. ``'{"orders": ["far goals first"]}'``), and prints the level's head-on structure (ordered pairs flying
opposite ways within reach of each other, and the most vehicles on one straight line), each pass, and the
head of the history of the first pass that gave up.

Usage (from outside the repository, so that the interpreter's installed proxplan is imported):
    cd /tmp && PY /path/to/benchmarks/why_128.py --layout pillar --n 128
    cd /tmp && PY /path/to/benchmarks/why_128.py --layout pillar --n 128 --one-pass --holding
    cd /tmp && PY /path/to/benchmarks/why_128.py --layout corridor --n 128 --lattice --seeds 4
    cd /tmp && PY /path/to/benchmarks/why_128.py --layout corridor --n 64 --flow
    cd /tmp && PY /path/to/benchmarks/why_128.py --layout corridor --n 128 --level 1
"""

from __future__ import annotations

import argparse
import re
import time
from collections import Counter

import numpy as np

# the --flow diagnostic's lane routes and flow timing (round 23B) live in the planner since round 27A
from proxplan.planner.swarm.lanes import BOTH_SIDES, KEEP_RIGHT, direction_groups, flow_timing, lane_routes

# a vehicle's name in a pass's history (swarm.priority writes "v012: why" for a vehicle that failed)
FAILED = re.compile(r"^(v\d+): (.*)$")
# head-on: headings more than this far apart (deg); collinear: both ends within this of the line (m)
HEAD_ON_DEG = 150.0
COLLINEAR_M = 0.01


def _passes_recorder(records: list[dict]):
    """A wrapper of ``priority._in_order`` recording each pass's outcome into ``records``."""
    import proxplan.planner.swarm.priority as priority

    inner = priority._in_order

    def recorded(problem, order, options, **kw):
        rec = {"vehicles": problem.n_agents, "hold_s": options.hold_s, "cpu0": time.process_time()}
        records.append(rec)
        try:
            result = inner(problem, order, options, **kw)
        except priority.PrioritizedFailed as err:
            rec.update(outcome="gave up", planned=err.planned, history=list(err.history))
            rec["cpu_s"] = time.process_time() - rec.pop("cpu0")
            raise
        rec.update(outcome="plan", planned=result.planned, history=list(result.history))
        rec["cpu_s"] = time.process_time() - rec.pop("cpu0")
        return result

    priority._in_order = recorded
    return inner


def _print_pass(rec: dict) -> None:
    failed: Counter = Counter()
    reasons: Counter = Counter()
    trapped = 0
    for line in rec["history"]:
        m = FAILED.match(line)
        if m:
            failed[m.group(1)] += 1
            reasons[re.sub(r"v\d+", "v", m.group(2)).split(" (")[0]] += 1
        if " past the predictions of " in line or " released the starts of " in line:
            trapped += 1
    print(
        f"  pass of {rec['vehicles']} vehicles, hold {rec['hold_s']:g} s: {rec['outcome']} after "
        f"{rec['planned']} plannings, {rec['cpu_s']:.1f} s CPU; planned past reserved starts {trapped} times"
    )
    if rec["outcome"] == "gave up":
        print(f"    last: {rec['history'][-1][:200]}")
    if failed:
        print(f"    vehicles that failed ({len(failed)}): {dict(failed.most_common(8))}")
        print(f"    how: {dict(reasons.most_common(4))}")


def cycle_pairs(problem, horizon_steps: int) -> int:
    """Ordered pairs (a, b) with a's start and goal both within keep-out of b's ideal track (its flight
    alone): a must leave before b passes its start and arrive after b passes its goal."""
    from proxplan.planner.swarm.occupancy import Occupancy
    from proxplan.planner.swarm.reserve import ideal_track, starts_in_the_way
    from proxplan.planner.swarm.tracks import GridTrack

    A = problem.n_agents
    ideal = {a: ideal_track(problem, a, horizon_steps) for a in range(A)}
    starts_on = starts_in_the_way(problem, ideal, horizon_steps)
    parked = [GridTrack(a, int(problem.type_index[a]), problem.goals_m[a].copy(), []) for a in range(A)]
    goals = Occupancy(problem, parked, horizon_steps)
    return sum(len(starts_on[b] & (goals.conflicting_agents(tr) - {b})) for b, tr in ideal.items() if tr is not None)


def head_on(problem) -> tuple[int, int]:
    """(ordered pairs of vehicles flying opposite ways, headings more than ``HEAD_ON_DEG`` apart, whose
    straight lines pass within the swarm's horizontal reach of each other (``reach_xy_m``) over a stretch
    both fly; the most vehicles whose straight lines lie on one line, within ``COLLINEAR_M``): the
    head-on structure prioritised planning meets in a level (round 26B: corridor-128's columns)."""
    s, g = problem.starts_m[:, :2], problem.goals_m[:, :2]
    d = g - s
    length = np.linalg.norm(d, axis=1)
    moving = length > 1e-9
    u = np.where(moving[:, None], d / np.where(moving, length, 1.0)[:, None], 0.0)
    pairs, most = 0, 1
    for a in np.flatnonzero(moving):
        normal = np.array([-u[a, 1], u[a, 0]])
        off_s, off_g = (s - s[a]) @ normal, (g - s[a]) @ normal  # signed distances from a's line, m
        along_s, along_g = (s - s[a]) @ u[a], (g - s[a]) @ u[a]  # abscissae along a's line, m
        overlap = np.minimum(np.maximum(along_s, along_g), length[a]) - np.maximum(np.minimum(along_s, along_g), 0.0)
        near = (np.abs(off_s) <= problem.reach_xy_m) & (np.abs(off_g) <= problem.reach_xy_m) & (overlap > 0.0)
        opposite = u @ u[a] < -np.cos(np.radians(HEAD_ON_DEG))
        pairs += int(np.sum(near & opposite & moving))
        most = max(most, int(np.sum((np.abs(off_s) <= COLLINEAR_M) & (np.abs(off_g) <= COLLINEAR_M) & moving)))
    return pairs, most


def level_alone(args) -> int:
    """One level of the stacked plan planned alone by prioritised planning with the level options
    (``plan._level_options``, changed by ``--level-options`` JSON), see module (``--level K``)."""
    import json
    from dataclasses import replace

    import proxplan.planner.swarm.plan as swarm_plan
    import proxplan.planner.swarm.priority as priority
    from proxplan.planfile.scenario_load import scenario_from_dict
    from proxplan.planner.formations import LAYOUTS
    from proxplan.planner.swarm import SwarmOptions, swarm_problem
    from proxplan.planner.swarm.frozen import unfrozen_problem
    from proxplan.planner.swarm.lanes import lanes_stage
    from proxplan.planner.swarm.levels import stack_levels
    from proxplan.planner.swarm.prioritised_stage import horizon_steps, prioritised_stage
    from proxplan.planner.swarm.stacked import level_subproblem, levelled_endpoints
    from proxplan.planner.swarm.tracks import GRID_DT_S
    from proxplan.planner.timing.profile import rest_to_rest

    scenario = scenario_from_dict(LAYOUTS[args.layout](args.n))
    opts = SwarmOptions(workers=1, reserve_starts=True)
    problem, _, _ = unfrozen_problem(swarm_problem(scenario))
    levels = stack_levels(problem, swarm_plan._stacking(scenario, problem)())
    if levels is None:
        print(f"{args.layout}-{args.n}: no stack of levels fits the free box")
        return 0
    lev_s, lev_g = levelled_endpoints(problem, levels)
    on_levels = replace(problem, starts_m=lev_s, goals_m=lev_g)
    group, z = levels.groups[args.level], levels.heights_m[args.level]
    agents = [a for a in range(problem.n_agents) if int(problem.type_index[a]) in group]
    sub = level_subproblem(on_levels, agents, levels.band_m(args.level))
    bound = max(
        rest_to_rest(float(np.linalg.norm(sub.goals_m[a] - sub.starts_m[a])), sub.limits[a], GRID_DT_S).duration_s
        for a in range(sub.n_agents)
    )
    changes = json.loads(args.level_options)
    changes = {k: tuple(v) if isinstance(v, list) else v for k, v in changes.items()}
    level_opts = replace(swarm_plan._level_options(opts), **changes)
    pairs, most = head_on(sub)
    print(
        f"{args.layout}-{args.n}, level {args.level} at {z:.2f} m: {sub.n_agents} vehicles, bound {bound:.2f} s, "
        f"horizon {horizon_steps(bound) * GRID_DT_S:.2f} s; {pairs} ordered head-on pairs, up to {most} "
        f"vehicles on one straight line; orders {level_opts.orders}, holds {level_opts.unplanned_hold_s}"
    )
    records: list[dict] = []
    inner = _passes_recorder(records)
    extra: dict = {}
    t0 = time.process_time()
    try:
        got = prioritised_stage(sub, bound, level_opts, extra, progress=None, deadline=None)
    finally:
        priority._in_order = inner
    print(f"  {extra['prioritised']}")
    print(f"  {extra['counts']}, {time.process_time() - t0:.1f} s CPU")
    if got is not None:
        print(f"  plan {max(tr.arrival_s for tr in got.tracks):.2f} s")
    else:  # what the level's planner asks next (round 27A)
        t0 = time.process_time()
        lanes = lanes_stage(sub, bound, extra)
        made = "" if lanes is None else f", {max(tr.arrival_s for tr in lanes.tracks) / bound:.2f}x the bound"
        print(f"  {extra['lanes']}{made}, {time.process_time() - t0:.1f} s CPU")
    for rec in records:
        _print_pass(rec)
    failed = next((rec for rec in records if rec["outcome"] == "gave up"), None)
    if failed is not None:
        print(f"  the first {args.history} lines of the first pass that gave up:")
        for line in failed["history"][: args.history]:
            print(f"    {line[:160]}")
    return 0


def one_pass(args) -> int:
    """One prioritised pass of the whole swarm (see module, ``--one-pass``)."""
    import math

    import proxplan.planner.swarm.wave as wave
    from proxplan.planfile.scenario_load import scenario_from_dict
    from proxplan.planner.formations import LAYOUTS
    from proxplan.planner.sampling.ordering import lower_bound_makespan_s
    from proxplan.planner.swarm import SwarmOptions, swarm_problem
    from proxplan.planner.swarm.frozen import unfrozen_problem
    from proxplan.planner.swarm.prioritised_stage import horizon_steps, prioritised_budget
    from proxplan.planner.swarm.priority import (
        PrioritizedFailed,
        PriorityOptions,
        dependency_order,
        in_collision_cap,
        prioritized_tracks,
    )

    if args.whole_box:
        wave.route_box = lambda problem, s, g: (problem.lo_m[:2].copy(), problem.hi_m[:2].copy())
    scenario = scenario_from_dict(LAYOUTS[args.layout](args.n))
    problem, _, _ = unfrozen_problem(swarm_problem(scenario))
    lower_bound = lower_bound_makespan_s(scenario)
    horizon = horizon_steps(lower_bound)
    opts = SwarmOptions()
    n = problem.n_agents
    options = PriorityOptions(
        max_repairs=math.ceil(opts.repairs_per_vehicle * n),
        max_plannings=prioritised_budget(problem, opts),
        hold_s=args.hold_s,
        reserve_starts=True,
        through=False,
        give_up_early=True,
        max_in_collision=in_collision_cap(n),
        holding=args.holding,
    )
    print(
        f"{args.layout}-{args.n}: {cycle_pairs(problem, horizon)} ordered pairs with start and goal on the other's track"
    )
    t0 = time.process_time()
    try:
        result = prioritized_tracks(problem, dependency_order(problem), options, horizon_steps=horizon)
    except PrioritizedFailed as err:
        print(f"  gave up after {err.planned} plannings, {time.process_time() - t0:.1f} s CPU")
        print(f"  planned through a holding point: {sum(' via a holding point' in h for h in err.history)}")
        print(f"  last: {err.history[-1][:200]}")
        return 0
    makespan = max(tr.arrival_s for tr in result.tracks.values())
    print(
        f"  plan {makespan:.2f} s = {makespan / lower_bound:.2f}x after {result.planned} plannings, "
        f"{result.repairs} repairs, {result.held} through a holding point, {time.process_time() - t0:.1f} s CPU"
    )
    return 0


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


def flow(args) -> int:
    """Direction groups planned alone, lane routes' hits and the flow timing, re-timed (``--flow``, round 23B;
    ``--group K``: lane routes and flow timing of direction group K alone)."""
    from proxplan.planfile.scenario_load import scenario_from_dict
    from proxplan.planner.formations import LAYOUTS
    from proxplan.planner.sampling.ordering import lower_bound_makespan_s
    from proxplan.planner.swarm import SwarmOptions, swarm_problem, swarm_timed
    from proxplan.planner.swarm.frozen import unfrozen_problem
    from proxplan.planner.swarm.plan import _retime_stage
    from proxplan.planner.swarm.stage import Stage

    doc = LAYOUTS[args.layout](args.n)
    scenario = scenario_from_dict(doc)
    problem, _, _ = unfrozen_problem(swarm_problem(scenario))
    bound = lower_bound_makespan_s(scenario)
    groups = direction_groups(problem)
    print(f"{args.layout}-{args.n}: bound {bound:.2f} s; {len(groups)} direction group(s)")
    for k, (heading, members) in enumerate(groups):
        if args.group is not None and k != args.group:
            continue
        names = {problem.names[a] for a in members}
        sub = dict(doc, vehicles={key: v for key, v in doc["vehicles"].items() if key in names})
        t0 = time.process_time()
        _, info = swarm_timed(scenario_from_dict(sub), SwarmOptions(workers=1, reserve_starts=True))
        print(
            f"  group {k}: heading ({heading[0]:+.2f}, {heading[1]:+.2f}), {len(members)} vehicles, planned alone by "
            f"the swarm layer: {info.makespan_s:.2f} s = {info.makespan_s / bound:.2f}x ({info.stage}; before "
            f"re-timing {info.initial_makespan_s:.2f} s), {time.process_time() - t0:.1f} s CPU"
        )
        if args.group is not None:
            problem, _, _ = unfrozen_problem(swarm_problem(scenario_from_dict(sub)))
    horizon = 4000
    t0 = time.process_time()
    routes, hits = lane_routes(problem, horizon, KEEP_RIGHT if args.keep_right else BOTH_SIDES)
    counts = Counter(len(h[0]) + len(h[1]) for h in hits.values())
    print(
        f"lane routes ({time.process_time() - t0:.1f} s CPU): other starts and goals on the route taken, vehicles: "
        f"{dict(sorted(counts.items()))}"
    )
    t0 = time.process_time()
    tracks, how = flow_timing(problem, routes, hits, horizon)
    if len(tracks) < problem.n_agents:
        print(f"flow timing: {how}, {time.process_time() - t0:.1f} s CPU")
        return 0
    before = max(tr.arrival_s for tr in tracks.values())

    def chains(a: int) -> list[np.ndarray]:
        return [np.array([problem.starts_m[a], problem.goals_m[a]]), routes[a]]

    stage = Stage([tracks[a] for a in range(problem.n_agents)], "prioritised", "flow timing", chains)
    final, _ = _retime_stage(problem, stage, before, SwarmOptions(), progress=None, deadline=None)
    after = max(tr.arrival_s for tr in final.values())
    print(
        f"flow timing: {how}, {before:.2f} s = {before / bound:.2f}x, re-timed {after:.2f} s = {after / bound:.2f}x, "
        f"{time.process_time() - t0:.1f} s CPU"
    )
    _print_rests(problem, final, 5)
    return 0


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--layout", default="pillar")
    ap.add_argument("--n", type=int, default=128)
    ap.add_argument("--one-pass", action="store_true", help="one prioritised pass only (see module)")
    ap.add_argument("--hold-s", type=float, default=1.0, help="with --one-pass: the hold of released starts, s")
    ap.add_argument("--holding", action="store_true", help="with --one-pass: PriorityOptions.holding")
    ap.add_argument("--whole-box", action="store_true", help="with --one-pass: the wavefront's whole-box fallback")
    ap.add_argument("--lattice", action="store_true", help="LaCAM alone on the stage's lattice (see module)")
    ap.add_argument("--seeds", type=int, default=4, help="with --lattice: seeds 0 .. N-1")
    ap.add_argument("--flow", action="store_true", help="direction groups alone, lane routes, flow timing (see module)")
    ap.add_argument("--group", type=int, default=None, help="with --flow: direction group K alone")
    ap.add_argument("--keep-right", action="store_true", help="with --flow: lane routes offset to the right only")
    ap.add_argument("--level", type=int, default=None, help="level K of the stacked plan alone (see module)")
    ap.add_argument("--level-options", default="{}", help="with --level: SwarmOptions changes, JSON")
    ap.add_argument("--history", type=int, default=40, help="with --level: lines of the failing pass's history")
    args = ap.parse_args()
    if args.level is not None:
        return level_alone(args)
    if args.flow:
        return flow(args)
    if args.one_pass:
        return one_pass(args)
    if args.lattice:
        return lattice_counts(args)

    import proxplan
    import proxplan.planner.swarm.priority as priority
    from proxplan.planfile.scenario_load import scenario_from_dict
    from proxplan.planner.formations import LAYOUTS
    from proxplan.planner.swarm import SwarmOptions, swarm_timed
    from proxplan.planner.timing.profile import rest_to_rest

    print(f"proxplan from {proxplan.__file__}")
    scenario = scenario_from_dict(LAYOUTS[args.layout](args.n))
    records: list[dict] = []
    inner = _passes_recorder(records)
    stages: list[tuple[float, str]] = []
    t0 = time.process_time()

    def progress(message: str, fraction: float | None = None) -> None:
        head = "".join(ch for ch in message if not ch.isdigit()).split("(")[0].strip()
        if not stages or stages[-1][1] != head:
            stages.append((time.process_time() - t0, message[:70]))

    try:
        timed, info = swarm_timed(scenario, SwarmOptions(workers=1, reserve_starts=True), progress=progress)
    finally:
        priority._in_order = inner
    cpu = time.process_time() - t0
    print(
        f"{args.layout}-{args.n}: stage {info.stage}, makespan {info.makespan_s:.2f} s = "
        f"{info.makespan_s / info.lower_bound_s:.2f}x the bound {info.lower_bound_s:.2f} s "
        f"(before re-timing {info.initial_makespan_s:.2f} s), {cpu:.1f} s CPU"
    )
    print(f"  coordination: {info.coordination}")
    print(f"  stacked: {info.stacked}")
    if info.lattice is not None:
        print(f"  lattice: {info.lattice.steps} steps, {info.lattice.nodes} configurations")
    print(f"  re-timing: {info.retiming}")
    print("\npasses of prioritised planning (in the order run)")
    for rec in records:
        _print_pass(rec)
    print("\nprogress (process CPU at the first message of each stage)")
    for t, head in stages:
        print(f"  {t:7.1f} s  {head}")
    hand_on = info.hand_on
    assert hand_on is not None
    problem = hand_on.problem
    tracks = hand_on.searched.tracks
    print(f"\nthe latest vehicles of the tracks before re-timing ({hand_on.searched.stage})")
    for tr in sorted(tracks, key=lambda tr: -tr.arrival_s)[:5]:
        a = tr.agent
        flying = sum(mv.steps for _, mv in tr.moves) * 0.025
        length = float(np.linalg.norm(problem.goals_m[a] - problem.starts_m[a]))
        alone = rest_to_rest(length, problem.limits[a], 0.025).duration_s
        route = sum(float(np.linalg.norm(mv.end_m - s)) for s, mv in _starts(tr))
        first = tr.moves[0][0] * 0.025 if tr.moves else 0.0
        print(
            f"  {problem.names[a]}: arrives {tr.arrival_s:.2f} s ({tr.arrival_s / alone:.1f}x its straight line "
            f"{alone:.2f} s, {length:.2f} m); {len(tr.moves)} moves, {route:.2f} m flown; flies {flying:.2f} s, "
            f"waits {tr.arrival_s - flying:.2f} s (first move at {first:.2f} s)"
        )
    final = hand_on.tracks
    if final is not None:
        print("\nthe latest vehicles of the final tracks (re-timed and repaired): rests of 0.25 s or more, where")
        _print_rests(problem, final, 5)
    return 0


def _rests(tr, min_s: float = 0.25) -> list[tuple[float, float, np.ndarray]]:
    """(from s, duration s, position m) of each rest of ``tr`` lasting ``min_s`` or more before its arrival."""
    still = ~tr.moving[: tr.arrival_step + 1]
    out = []
    k = 0
    while k < still.size:
        if still[k]:
            j = k
            while j < still.size and still[j]:
                j += 1
            if j < still.size and (j - k) * 0.025 >= min_s:
                out.append((k * 0.025, (j - k) * 0.025, tr.positions_m[k]))
            k = j
        else:
            k += 1
    return out


def _print_rests(problem, tracks: dict, count: int) -> None:
    """The ``count`` latest of ``tracks`` (by agent): each rest (at its start, at its goal or aside) and
    when its goal is clear of every other track for good (the stream has passed it), s."""
    from proxplan.planner.swarm.occupancy import Occupancy
    from proxplan.planner.timing.profile import rest_to_rest

    horizon = max(tr.arrival_step for tr in tracks.values()) + 2
    occ = Occupancy(problem, list(tracks.values()), horizon)
    for tr in sorted(tracks.values(), key=lambda tr: -tr.arrival_s)[:count]:
        a = tr.agent
        s, g = problem.starts_m[a], problem.goals_m[a]
        alone = rest_to_rest(float(np.linalg.norm(g - s)), problem.limits[a], 0.025).duration_s
        occ.remove(a)
        busy = np.flatnonzero(occ.forbidden_holds(a, g))
        occ.put(tr)
        clear = (busy[-1] + 1) * 0.025 if busy.size else 0.0
        where = []
        for t0, dt, q in _rests(tr):
            at = (
                "start"
                if np.linalg.norm(q - s) < 1e-6
                else "goal"
                if np.linalg.norm(q - g) < 1e-6
                else (f"aside ({q[0]:.2f}, {q[1]:.2f}, {q[2]:.2f})")
            )
            where.append(f"{dt:.2f} s at {at} from {t0:.2f} s")
        print(
            f"  {problem.names[a]}: arrives {tr.arrival_s:.2f} s ({alone:.2f} s alone); its goal clear of the others "
            f"for good from {clear:.2f} s; rests: {'; '.join(where) or 'none'}"
        )


def _starts(tr):
    """(start point, move) of each move of a track, m."""
    cur = np.asarray(tr.start_m, dtype=float)
    for _, mv in tr.moves:
        yield cur, mv
        cur = np.asarray(mv.end_m, dtype=float)


if __name__ == "__main__":
    raise SystemExit(main())
