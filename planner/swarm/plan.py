"""Roadmap planning of a swarm (``--method roadmap``, and ``sampling``/``optimized`` for formation
changes of ``ROADMAP_MIN_VEHICLES`` or more): scenario -> shared roadmap -> multi-agent search ->
Ruckig timing -> :class:`proxplan.planfile.Plan`.

The timed trajectory of each vehicle is exactly what the search reserved: its runs are the
rest-to-rest, phase-synchronised Ruckig segments (:func:`proxplan.planner.timing.ruckig_segment`,
straight lines) starting at their window, holds in between; the continuous motion stays on the atoms
reserved for each window, so the per-window conflict-freedom of the search carries over to
continuous time. The verifier checks the assembled plan as any other.

Bounds reported in ``plan.metrics``: ``lower_bound_s`` (largest straight-line rest-to-rest time of
any vehicle, :func:`proxplan.planner.sampling.ordering.lower_bound_makespan_s`), ``roadmap_lower_bound_s``
(largest admissible roadmap time, the search's heuristic at the start) and ``makespan_over_lower_bound``:
the plan is within that factor of the optimum (an a-posteriori bound; PBS has no a-priori factor).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from proxplan.planfile import Scenario
from proxplan.planner.errors import InfeasibleError
from proxplan.planner.swarm.keepout import keepout_for
from proxplan.planner.swarm.pbs import SearchResult, pbs, prioritized
from proxplan.planner.swarm.roadmap import SAMPLE_M, Roadmap, build_roadmap
from proxplan.planner.swarm.runs import Agent
from proxplan.planner.swarm.search import Search
from proxplan.planner.timing.paths import TimedPath
from proxplan.planner.timing.segments import ruckig_segment

SEARCHES = ("pbs", "pp")
ROADMAP_MIN_VEHICLES = 24  # formation changes with at least this many vehicles use the roadmap
WINDOW_FRACTION = 0.5  # window = this x lattice spacing / fastest vehicle's speed


@dataclass
class RoadmapOptions:
    search: str = "pbs"  # "pbs" or "pp"
    max_expansions: int = 40000  # per low-level search (a count, not a time)
    max_nodes: int = 300  # PBS high-level nodes
    weight: float = 1.5  # weighted A*: every single-vehicle search within this factor of its optimum


def roadmap_applicable(scenario: Scenario) -> str | None:
    """None when the roadmap can express the scenario, else why not (docks, hovering vehicles)."""
    for name, task in scenario.vehicles.items():
        if task.dock_with is not None:
            return f"vehicle {name!r} docks (the roadmap has no dock approach)"
        if task.goal_m is None and not task.hover:
            return f"vehicle {name!r} has no goal"
    return None


def build(scenario: Scenario) -> tuple[Roadmap, list[Agent], float]:
    """Roadmap, agents and window length (s) of ``scenario``."""
    from proxplan.costmaps import effects_key
    from proxplan.planner.checks.constraints import build_checker

    names = list(scenario.vehicles)
    type_of: dict = {}
    vehicles: list = []
    for n in names:
        v = scenario.vehicles[n].vehicle
        if v not in type_of:
            type_of[v] = len(vehicles)
            vehicles.append(v)
    fx = effects_key(getattr(scenario, "effects", ()))
    keep = {}
    for ia, va in enumerate(vehicles):
        for ib, vb in enumerate(vehicles):
            keep[(ia, ib)] = keepout_for(
                va, vb, limits=scenario.limits, field_form=scenario.field_form, effects=fx, sample_m=SAMPLE_M
            )
    widest = max(names, key=lambda n: (scenario.vehicles[n].vehicle.body_radius_m, n))
    chk = build_checker(scenario, widest, [], margin_m=float(scenario.limits.tracking_margin_m))
    lo, hi = np.asarray(chk.lo), np.asarray(chk.hi)
    boxes = np.asarray(chk.boxes, dtype=float).reshape(-1, 6)
    endpoints = []
    agents = []
    for n in names:
        task = scenario.vehicles[n]
        goal = task.start_m if task.hover else task.goal_m
        assert goal is not None
        endpoints.append(task.start_m)
        start = len(endpoints) - 1
        if not np.allclose(goal, task.start_m, atol=1e-9):  # a vehicle that stays has one endpoint
            endpoints.append(goal)
        agents.append(Agent(n, type_of[task.vehicle], task.kinematic_limits, start, len(endpoints) - 1))
    rm = build_roadmap(np.array(endpoints), lo, hi, boxes, keep, tuple(v.name for v in vehicles))
    v_max = max(a.limits.max_speed_mps for a in agents)
    window = WINDOW_FRACTION * float(rm.spacing_m[0]) / v_max
    return rm, agents, window


def search_plan(scenario: Scenario, options: RoadmapOptions | None = None) -> tuple[Search, SearchResult, dict]:
    """Run the multi-agent search; (search, result, info with timings and bounds)."""
    options = options or RoadmapOptions()
    if options.search not in SEARCHES:
        raise ValueError(f"search must be one of {SEARCHES}, got {options.search!r}")
    t0 = time.perf_counter()
    rm, agents, window = build(scenario)
    t1 = time.perf_counter()
    search = Search(rm, agents, window, max_expansions=options.max_expansions, weight=options.weight)
    lb = max(search.lower_bound_windows(a) for a in agents)
    horizon = int(max(4.0 * lb, lb + 150)) + 10
    if options.search == "pbs":
        res = pbs(search, horizon, max_nodes=options.max_nodes)
    else:
        res = prioritized(search, horizon)
    t2 = time.perf_counter()
    info = {
        "roadmap_vertices": int(rm.vertex_ok.sum()),
        "roadmap_atoms": rm.n_atoms,
        "roadmap_spacing_m": [round(float(x), 4) for x in rm.spacing_m],
        "conflict_pairs": int(sum(c.nnz for c in rm.conflicts.values())),
        "window_s": window,
        "roadmap_build_s": round(t1 - t0, 3),
        "search_s": round(t2 - t1, 3),
        "search": res.method,
        "high_level_nodes": res.high_level_nodes,
        "low_level_calls": res.low_level_calls,
        "expansions": res.expansions,
        "roadmap_lower_bound_s": lb * window,
    }
    return search, res, info


def timed_paths(search: Search, paths) -> dict[str, TimedPath]:
    """Ruckig-timed trajectory of each vehicle: its runs at their windows, holds in between."""
    out = {}
    for ag, p in zip(search.agents, paths, strict=True):
        knots = [0.0]
        pts = [search.node_pos(search.start_node(ag)) if not p.moves else search.node_pos(p.moves[0].a)]
        pts[0] = search.rm.endpoints_m[ag.start]
        segs: list = []
        for mv in p.moves:
            if mv.a == mv.b:
                continue
            t0 = mv.k0 * search.window_s
            if t0 > knots[-1] + 1e-12:
                segs.append(None)
                knots.append(t0)
                pts.append(pts[-1])
            a = search.rm.endpoints_m[mv.a - search.nv] if mv.a >= search.nv else search.rm.position(mv.a)
            b = search.rm.endpoints_m[mv.b - search.nv] if mv.b >= search.nv else search.rm.position(mv.b)
            if mv.b == search.goal_node(ag):
                b = search.rm.endpoints_m[ag.goal]
            traj = ruckig_segment(a, b, ag.limits)
            segs.append(traj)
            knots.append(t0 + float(traj.duration))
            pts.append(b)
        out[ag.name] = TimedPath(np.array(knots), np.array(pts), segs)
    return out


def roadmap_timed(scenario: Scenario, options: RoadmapOptions | None = None) -> tuple[dict[str, TimedPath], dict]:
    """(timed path per vehicle, info with timings and bounds) of the roadmap plan of ``scenario``;
    InfeasibleError when the roadmap cannot express it or the search fails.
    :func:`proxplan.planner.pipeline.plan_roadmap` assembles them into a Plan."""
    from proxplan.planner.sampling.ordering import lower_bound_makespan_s

    why = roadmap_applicable(scenario)
    if why is not None:
        raise InfeasibleError("-", "roadmap", f"the roadmap cannot express this scenario: {why}")
    search, res, info = search_plan(scenario, options)
    if res.paths is None:
        name = res.message.split("'")[1] if "'" in res.message else "-"
        raise InfeasibleError(name, "roadmap search", res.message)
    timed = timed_paths(search, res.paths)
    lb = lower_bound_makespan_s(scenario)
    end = max(tp.duration_s for tp in timed.values())
    info.update(
        {
            "lower_bound_s": lb,
            "makespan_over_lower_bound": (end / lb) if lb > 0 else math.nan,
            "sum_of_costs_s": float(sum(tp.duration_s for tp in timed.values())),
            "note": (
                f"roadmap: {info['roadmap_vertices']} lattice vertices, spacing {info['roadmap_spacing_m']} m, "
                f"{res.method.upper()} ({res.high_level_nodes} nodes, {res.low_level_calls} single-vehicle "
                f"searches); makespan {end:.2f} s <= {(end / lb) if lb > 0 else math.nan:.2f} x lower bound {lb:.2f} s"
            ),
        }
    )
    return timed, info
