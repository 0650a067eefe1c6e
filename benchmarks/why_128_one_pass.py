"""``why_128.py --one-pass`` (round 21B): one prioritised pass of the whole swarm (see benchmarks/why_128.py;
split by mode in round 28A)."""

from __future__ import annotations

import time


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
    from proxplan.planner.swarm.priority import in_collision_cap, prioritized_tracks
    from proxplan.planner.swarm.priority_options import PrioritizedFailed, PriorityOptions
    from proxplan.planner.swarm.priority_order import dependency_order

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
