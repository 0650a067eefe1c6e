"""``why_128.py --level K`` (round 26B): one level of the stacked plan planned alone, its head-on structure
(see benchmarks/why_128.py; split by mode in round 28A)."""

from __future__ import annotations

import time

import numpy as np
from why_128_common import _passes_recorder, _print_pass
from why_raised import level_problem

# head-on: headings more than this far apart (deg); collinear: both ends within this of the line (m)
HEAD_ON_DEG = 150.0
COLLINEAR_M = 0.01


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
    from proxplan.planner.swarm import SwarmOptions
    from proxplan.planner.swarm.lanes import lanes_stage
    from proxplan.planner.swarm.prioritised_stage import horizon_steps, prioritised_stage
    from proxplan.planner.swarm.stacked import alone_steps
    from proxplan.planner.swarm.tracks import GRID_DT_S

    got_level = level_problem(args.layout, args.n, args.level)
    if got_level is None:
        print(f"{args.layout}-{args.n}: no stack of levels fits the free box")
        return 0
    sub, levels = got_level
    z = levels.heights_m[args.level]
    opts = SwarmOptions(workers=1, reserve_starts=True)
    bound = alone_steps(sub) * GRID_DT_S
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
