"""The knobs of the swarm layer (:class:`SwarmOptions`), read by every stage of
:mod:`proxplan.planner.swarm.plan`; every budget is a count (the same plan on every machine)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Literal

__all__ = ["SwarmOptions"]


@dataclass(frozen=True)
class SwarmOptions:
    """Knobs of the swarm layer; every budget is a count (same plan on every machine)."""

    max_run: int = 4  # longest straight move of one coordination step, in lattice edges
    max_nodes: int = 3000  # LaCAM configurations before the coordination search gives up
    # LaCAM's PIBT proposals before it gives up (most fail or revisit a configuration and add none);
    # set on the named layouts at 64 fixed: grid 60, corridor 2378 to a plan; pillar none in 5800 (before
    # round 12A, when most PIBT proposals failed; now one without a constraint never does, swarm.lacam)
    max_proposals: int = 4000
    # prioritised planning's budget: single-vehicle plannings over all its passes (orders, holds,
    # repairs), per vehicle; once spent the best plan found so far is kept, or the lattice plan
    # is the answer (a count: the same plan on every machine). Set on the named layouts at 64
    # fixed (docs/planner.md): two orders need 2, a failing pass 1-3, a pass with repairs 2-3
    plannings_per_vehicle: float = 6.0
    # LaCAM searches (seeds seed + k, SHARING one budget of max_nodes / max_proposals: the first has all of
    # it, each further one what the others left) of which the lattice plan arriving first is kept
    # (swarm.complete_stages.lattice_stage; a budget each took grid-256 past 500 s of CPU with no plan,
    # stop 58). Its plan depends on the seeded tie-breaks
    # of PIBT: pillar-128 fixed, lock-step makespans of seeds 0-4 61.03, 50.05, 66.48, 43.60, 53.93 s (7.4-11.2x
    # the bound; round 20B, benchmarks/why_128.py), corridor-128 seeds 0-3 102.33, 102.68, 114.15, 113.25 s;
    # each search costs 5-13 s of CPU there. Set watching pillar-128 and corridor-128 (docs/planner.md, stop
    # 58), not the randomised family
    lattice_seeds: int = 4
    passes: int = 3  # continuous re-timing passes
    # where prioritised planning gives up, also the stacked plan (swarm.stacked): each group of types
    # on a level of its own, where the free box is tall enough for the levels never to conflict,
    # each level planned apart; the shorter of it and the lattice plan kept (False: the lattice plan
    # alone, for measuring the cause). On: grid-64 fixed 6.13x -> 2.11x, corridor-64 8.96x -> 4.84x
    # (docs/planner.md, stop 52 round 14A)
    levels: bool = True
    prioritized: bool = True  # try prioritised continuous planning before the lattice coordination
    # prioritised planning's repair budget, per vehicle of a group (rounded up): on the named layouts at
    # 32 vehicles the plans that repaired at all needed 1-3 repairs; 2 per vehicle let grid-64 run
    # for minutes on failing passes
    repairs_per_vehicle: float = 0.25
    orders: tuple[str, ...] = ("dependencies first", "longest first")  # prioritised planning's orders (ORDERS)
    # a vehicle not planned yet is assumed to hold its start this long, then to leave on its straight
    # route, s: tried in turn until prioritised planning finds a plan (a longer hold leaves it more
    # room). No hold (0.0) was measured first and lost on grid and pillar layouts (see docs/planner.md)
    unplanned_hold_s: tuple[float, ...] = (1.0, 2.5)
    # on a level of the stacked plan (swarm.raised.a_level) every vehicle of a pass also along its routes
    # raised over the others (swarm.raised; round 29A): corridor-64's Crazyflie level alone 21.12 -> 14.12 s,
    # pillar-64's 10.60 -> 9.25 s. Not on the whole swarm: corridor-64 then ran past 400 s (95 s CPU)
    # (round 30A: planned as a second arm beside the flat passes, the shorter kept, ties the flat arm's:
    # prioritised_stage.prioritised_stage)
    raised_routes: bool = True
    # the raised arm's single-vehicle plannings over all its passes, per vehicle of the level (rounded up;
    # a pass that cannot plan its queued vehicles within what is left gives up at once). Set watching the
    # levels of corridor and pillar at 64 and 128 (round 30A, benchmarks/why_raised.py): their raised
    # passes that found a plan made 1.01-1.21 plannings per vehicle; corridor-128's, which gives up, 391
    # plannings for 86 vehicles at ~0.5 s of CPU each
    raised_plannings_per_vehicle: float = 1.5
    # a vehicle not planned yet holds its start until it is planned (swarm.reserve), instead of the
    # prediction above; the hold then applies to the starts released for a vehicle in their way. None: on
    # with fixed goals, off where the goals were assigned (assign_goals: by_type, decided by
    # planner.pipeline). With fixed goals at 64 the predictions start-trapped every
    # pass on grid and pillar (sixth round); reserved starts gave pillar-64 and random-1 plans where there
    # were none (seventh round). By type they made grid-64 1.63x -> 1.84x and corridor-64 2.23x -> 3.88x
    # (an assignment rarely puts a goal on another's start; docs/planner.md, seventh round; a default set
    # watching those named layouts). Called directly (not through the pipeline), None means on.
    reserve_starts: bool | None = None
    # fly through waypoints without stopping (else rest to rest at each): "retime" in the re-timing
    # passes only (each vehicle along its own route, against everyone's final tracks: never worse),
    # "always" in prioritised planning too, "never". Off by default: on the named layouts it did not
    # shorten the makespan for its CPU time (docs/planner.md, "Causes measured one at a time")
    through_waypoints: Literal["never", "retime", "always"] = "never"
    # also try: keep the straight lines in no conflict and plan only the others around them. Off by
    # default: on the named layouts at 32 vehicles it never gave the shorter plan (docs/planner.md)
    keep_straight: bool = False
    # after re-timing, once on the plan kept, plan the latest vehicles again together with the vehicles
    # in their way (swarm.makespan; False: for measuring the cause alone; True: on every plan). None:
    # on, but not on the lattice plan (round 14A: nothing replaced on grid-64 and corridor-64 fixed). On
    # the stacked plan (round 19B: grid-64/128 shortened) its result is checked by the verifier and given
    # up where it fails (round 21A: grid-256's repaired plan failed verify, and the pipeline planned
    # again past the CPU cap, stop 58). Set watching the named layouts at 64 (docs/planner.md, round
    # 13A): on the prioritised plans with fixed goals pillar 2.73x -> 2.62x for 57 plannings, circle
    # unchanged (13); on the lattice plans nothing shorter: grid and corridor fixed (in-process, 64
    # plannings: 0 and 1 neighbourhoods replaced, the makespan unchanged, 5 and 22 s of CPU) and pillar
    # by type (62 plannings, none replaced, 7 s): the vehicles in the latest one's way cannot be planned
    # again among the lock-step tracks. On the prioritised plans by type it was on before (grid-64
    # 1.91x -> 1.63x, fifth round) and stays so. Decided by the swarm layer (no caller sets it)
    makespan_repair: bool | None = None
    # where goals were assigned, also the vehicles of each group of conflicting straight lines passing
    # together (swarm.passes; the shorter plan kept): grid-64 by type 1.63x -> 1.32x (round 23S). False:
    # for measuring the other stages alone (the makespan repair's grid-20 test)
    pass_together: bool = True
    # where goals were assigned, the vehicles giving way (swarm.give_way: passing together, yielding) are
    # tried BEFORE prioritised planning, asked for a plan arriving within this factor of the straight-line
    # lower bound (a certified bound: no plan is shorter); where one is found, prioritised planning is not
    # run (it can shorten that plan by at most this factor). The value is the target (issue 37:
    # by type <= 1.3x the bound), not tuned. Pillar-64 by type: prioritised planning gave up after 329
    # plannings (~10 s) before the passing plan (1.16 B) was found (round 25S). None: prioritised first
    enough_factor: float | None = 1.3
    # one more pass of prioritised planning with both wavefronts per vehicle (the widest disc at every
    # height and discs for the heights the route flies at, swarm.wave; the earlier arrival kept,
    # priority.plan_one), in the order and hold of the pass that gave the plan without, on what is left
    # of prioritised planning's count budget; the shorter of the two whole plans kept (each re-timed and
    # repaired; ties: the plan without), so never longer than without. No pass where prioritised
    # planning gave up (its budget spent: the lattice plan). None: on with fixed goals for up to
    # HEIGHTS_MAX_VEHICLES vehicles, off where the goals were assigned (Scenario.assign_goals: by_type).
    # Set watching the named layouts only (docs/planner.md, round 12B): fixed goals at 64, pillar 3.17x
    # -> 2.73x and circle 1.56x -> 1.51x for about +10 / +6 s of CPU, grid and corridor no pass (both
    # gave up); by type at 64 it shortened no named layout for +1.4 to +16.5 s of CPU (round 11S)
    heights: bool | None = None
    workers: int = 0  # Dask workers for groups that never interact (0: one per core; 1: none)
    # grow every vehicle's keep-outs by the bound on its predicted tracking error in any plan this
    # layer can time (swarm.tracking_bound), so that the verifier does not reject the first plan
    # by millimetres (False: only by ``deflection_m``, as before; for measuring the cause alone)
    tracking_bound: bool = True
    seed: int = 0
    # per vehicle name: its predicted deflection under the plan's own disturbance, m; a pair's
    # keep-out grows by the sum of its two vehicles' values (as in the verifier)
    deflection_m: Mapping[str, float] = field(default_factory=dict)
