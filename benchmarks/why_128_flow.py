"""``why_128.py --flow`` (round 23B): direction groups planned alone, lane routes and the flow timing (see
benchmarks/why_128.py; split by mode in round 28A)."""

from __future__ import annotations

import time
from collections import Counter

import numpy as np
from why_128_common import _print_rests

from proxplan.planner.swarm.lanes import BOTH_SIDES, KEEP_RIGHT, direction_groups, flow_timing, lane_routes


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
