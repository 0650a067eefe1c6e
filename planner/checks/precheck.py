"""Checks before any search: swarm size, and starts / goals that can never be valid.

``MAX_VEHICLES`` bounds the scenarios the planners accept (a user mistake beyond it, exit 2,
instead of hours of planning; the scenario loader rejects such a file before building its vehicles).
:func:`check_starts_and_goals` checks every start at t = 0 against the other vehicles' starts and
every goal (a vehicle holds it forever) against the other vehicles' final positions, in one
vectorised pass over the pairs a ``scipy.spatial.cKDTree`` query finds (1000 vehicles in a fraction
of a second): starts or goals closer than the pair's separation and a goal inside another goal's
downwash cut-off are user mistakes (``UserError``, exit 2, naming both vehicles); any other
violation of the planner's pair rules (downwash cut-offs both ways, keep-out ellipsoid, by
``--method``) is an :class:`InfeasibleError` naming the vehicle and the constraint, with the same
verdicts as the per-state checker (:func:`proxplan.planner.checks.validity.rule_kind`).

A goal is reached *moving*: while either vehicle of a pair flies, the verifier grows the pair's
keep-out (separation, downwash cut-off, invalid zone) by the tracking tube ``limits.tracking_margin_m``
(``verify/pair_checks.py``, ``check_pairs``), and so does the planners' checker. Of two goals the
later arrival is made moving, so a goal valid at rest but inside the keep-out of another vehicle's
final position grown by the tube fails the verifier whatever the plan; :func:`check_goal_tubes` says
so before any search, naming the vehicle, the source of the keep-out, how far the goal lies inside it
and the nearest goal clear of it (one vectorised check of candidate points on spheres around the
goal). The rule is :func:`rest_pair_conflicts`, the verifier's: the tube and no more. A planner that
searches with a margin of its own (the sampling planner's ``PLAN_MARGIN_M``) imports the same rule
to find the pairs that only its margin would keep apart at a goal or a start, and searches those
with the verifier's rule (issue 37, round 37Z).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from proxplan.fileio import UserError
from proxplan.physics import Vehicle
from proxplan.planfile import MAX_VEHICLES, Scenario
from proxplan.planner.checks.constraints import MODES, ConflictChecker, Track, build_checker, cutoff_table
from proxplan.planner.checks.goal_need import pair_need
from proxplan.planner.checks.validity import BatchChecker, bracket_table, cutoff_lookup, rule_kind, stack_tables
from proxplan.planner.errors import InfeasibleError

GOAL_SEARCH_STEP_M = 0.005  # radius step of the nearest-clear-goal search, m
GOAL_SEARCH_MAX_M = 1.0  # largest goal displacement the search proposes, m
GOAL_SEARCH_DIRECTIONS = 256  # directions per sphere (Fibonacci lattice)
__all__ = [
    "MAX_VEHICLES",
    "check_goal_loops",
    "check_goal_tubes",
    "check_starts_and_goals",
    "check_swarm_size",
    "nearest_clear_goal",
    "rest_pair_conflicts",
]


def check_swarm_size(scenario: Scenario) -> None:
    """UserError when the scenario has no vehicle or more than ``MAX_VEHICLES``."""
    n = len(scenario.vehicles)
    where = f"{scenario.source_path}: " if scenario.source_path else ""
    if n == 0:
        raise UserError(f"{where}vehicles: expected at least one vehicle, got none")
    if n > MAX_VEHICLES:
        raise UserError(
            f"{where}vehicles: expected at most {MAX_VEHICLES} vehicles, got {n} (split the swarm into groups)"
        )


def _sphere_directions(k: int) -> np.ndarray:
    """(k, 3) unit vectors spread evenly over the sphere (Fibonacci lattice), deterministic."""
    i = np.arange(k) + 0.5
    z = 1.0 - 2.0 * i / k
    phi = np.pi * (1.0 + 5.0**0.5) * i
    r = np.sqrt(1.0 - z**2)
    return np.column_stack([r * np.cos(phi), r * np.sin(phi), z])


def nearest_clear_goal(batch: BatchChecker, goal_m: np.ndarray) -> np.ndarray | None:
    """The point nearest to ``goal_m`` (3,) that ``batch`` finds valid (to ``GOAL_SEARCH_STEP_M``),
    searched on spheres of growing radius up to ``GOAL_SEARCH_MAX_M``; None if there is none."""
    dirs = _sphere_directions(GOAL_SEARCH_DIRECTIONS)
    radii = np.arange(1, int(round(GOAL_SEARCH_MAX_M / GOAL_SEARCH_STEP_M)) + 1) * GOAL_SEARCH_STEP_M
    pts = (goal_m[None, None, :] + radii[:, None, None] * dirs[None, :, :]).reshape(-1, 3)
    static, code = batch.conflict_codes(pts, np.zeros(len(pts)))
    ok = np.flatnonzero((static < 0) & (code < 0))
    return None if ok.size == 0 else pts[ok[0]]


def rest_pair_conflicts(
    scenario: Scenario,
    name: str,
    point_m: np.ndarray,
    others_m: Mapping[str, np.ndarray],
    *,
    mode: str,
    margin_m: float = 0.0,
    extra_tube_m: Mapping[str, float] | None = None,
) -> dict[str, str]:
    """The vehicles of ``others_m`` (name -> where it rests, m) whose keep-out holds ``name`` at
    ``point_m`` (3,), m, while either of the two moves, each with the constraint broken (named as
    ``ConflictChecker.conflict`` names it), in the order of ``others_m``: the verifier's rule for a
    pair of which one arrives at, or leaves, its resting point (the keep-out grown by the tracking
    tube ``limits.tracking_margin_m`` and by both vehicles' ``extra_tube_m``, their predicted
    deflections, m), grown by ``margin_m`` (m; 0: the verifier's rule alone). Pairs only; the
    workspace and obstacles are not checked here."""
    point = np.asarray(point_m, dtype=float)
    tracks = [
        Track.static(o, scenario.vehicles[o].vehicle, np.asarray(p, dtype=float))
        for o, p in others_m.items()
        if o != name
    ]
    chk = build_checker(scenario, name, tracks, mode=mode, tube=True, margin_m=margin_m, extra_tube_m=extra_tube_m)
    free = (-math.inf,) * 3, (math.inf,) * 3
    x, y, z = (float(c) for c in point)
    out = {}
    for rule in chk.rules:
        bad = ConflictChecker(name, free[0], free[1], [], [rule]).conflict(x, y, z, 0.0)
        if bad is not None:
            out[rule.track.name] = bad
    return out


def check_goal_tubes(scenario: Scenario, *, mode: str) -> None:
    """InfeasibleError for the first goal that is valid at rest but lies inside the keep-out of
    another vehicle's final position grown by the tracking tube (:func:`rest_pair_conflicts`, the
    verifier's rule while either moves: the later of the two arrives moving), with ``details``: the
    other vehicle, the tube, how far the goal must move, the nearest clear goal. No planner's search
    margin: a goal the verifier can pass is not rejected here."""
    tube = float(scenario.limits.tracking_margin_m)
    if tube <= 0.0:
        return
    final = {n: scenario.final_position_m(n) for n in scenario.vehicles}
    for name, task in scenario.vehicles.items():
        if task.hover or task.dock_with is not None or task.goal_m is None:
            continue  # docks meet on purpose (exempt on their approach); hovering vehicles do not arrive
        others = {o: p for o, p in final.items() if o != name and scenario.vehicles[o].dock_with != name}
        goal = np.asarray(task.goal_m, dtype=float)
        checker = build_checker(
            scenario, name, [Track.static(o, scenario.vehicles[o].vehicle, p) for o, p in others.items()], mode=mode
        )
        if checker.static_conflict(*(float(c) for c in goal)) is not None:
            continue  # outside the workspace or in an obstacle: the planner names it
        hits = rest_pair_conflicts(scenario, name, goal, others, mode=mode)
        if not hits:
            continue
        other, bad = next(iter(hits.items()))
        need = pair_need(scenario, name, other, bad, goal, final[other], mode=mode)
        clear = nearest_clear_goal(BatchChecker.from_checker(checker), goal)
        shift = None if clear is None else float(np.linalg.norm(clear - goal))
        where = f"{scenario.source_path}: vehicles.{name}.goal: " if scenario.source_path else ""
        suggestion = (
            f"the nearest goal clear of it is {np.round(clear, 3).tolist()} ({shift:.3f} m away)"
            if clear is not None
            else f"no goal within {GOAL_SEARCH_MAX_M:g} m is clear of it"
        )
        raise InfeasibleError(
            name,
            bad,
            f"{where}vehicle {name!r}: its goal {np.round(goal, 4).tolist()} is clear at rest but inside the "
            f"'{bad}' keep-out grown by the tracking tube (limits.tracking_margin_m = {tube:g} m), which applies "
            f"while it arrives; {need.text(other)}; {suggestion}",
            details={
                "kind": "goal-in-tube",
                "vehicle": name,
                "other_vehicle": other,
                "constraint": bad,
                "tracking_margin_m": tube,
                "goal_m": goal.tolist(),
                "shortfall_m": shift,
                "suggested_goal_m": None if clear is None else np.round(clear, 4).tolist(),
                **need.details(),
            },
        )


def check_starts_and_goals(scenario: Scenario, *, mode: str) -> None:
    """Every start (at t = 0, against the other starts) and every goal (held for ever, against the
    other vehicles' final positions) in one vectorised pass over the pairs that can conflict (a
    ``scipy.spatial.cKDTree`` query, then :func:`rule_kind` on arrays of pairs). Both at rest: no
    tracking tube. Dock pairs are exempt (they meet on purpose).

    User mistakes first, ``UserError`` (exit 2) naming both vehicles: starts or goals closer than
    the pair's separation (max(limits.min_separation_m, sum of body radii), m), then a goal inside the
    cut-off r_cut(dz) of a goal above it. Then, for ``mode``'s rules (separation, downwash cut-offs
    both ways or keep-out ellipsoid), ``InfeasibleError`` for the first vehicle (file order; starts
    before goals) whose start or goal breaks one, naming the vehicle and the constraint as
    ``ConflictChecker.conflict`` does (the first other vehicle in file order). A goal conflict is the
    moving vehicle's (a hovering or docking vehicle's is named from the other side); a start or goal
    outside the workspace or in an obstacle is left to the planner, which names it."""
    where = f"{scenario.source_path}: " if scenario.source_path else ""
    sets = [_Points.of(scenario, "start"), _Points.of(scenario, "goal")]
    for pts in sets:
        _too_close(pts, scenario.limits.min_separation_m, where)
    tables = _CutTables(scenario, sets if mode == "downwash" else sets[1:])  # the goals' always (user mistakes)
    _goal_in_cutoff(sets[1], tables, scenario.limits.authority_fraction, where)
    for pts in sets:
        _first_conflict(scenario, pts, tables, mode)


@dataclass(frozen=True)
class _Points:
    """The starts or the final positions of a scenario's vehicles as arrays (file order)."""

    kind: str  # "start" or "goal"
    names: list[str]
    xyz: np.ndarray  # (N, 3) m
    vehicles: list[Vehicle]  # (N,)
    radius: np.ndarray  # (N,) body radii, m
    checked: np.ndarray  # (N,) bool: a conflict here is this vehicle's (see check_starts_and_goals)
    dock: set[tuple[int, int]]  # dock pairs (docker, target) as indices, both present

    @classmethod
    def of(cls, scenario: Scenario, kind: str) -> _Points:
        """Starts of every vehicle, or where each non-docking vehicle ends (goal, or start for a
        hovering one)."""
        tasks = scenario.vehicles
        if kind == "start":
            names = list(tasks)
            xyz = [tasks[n].start_m for n in names]
        else:
            names = [n for n, t in tasks.items() if t.dock_with is None and (t.hover or t.goal_m is not None)]
            xyz = [scenario.final_position_m(n) for n in names]  # goal, or start when hovering
        index = {n: i for i, n in enumerate(names)}
        dock = {(index[n], index[t.dock_with]) for n, t in tasks.items() if n in index and t.dock_with in index}
        checked = np.array([kind == "start" or not tasks[n].hover for n in names], dtype=bool)
        return cls(
            kind,
            names,
            np.asarray(xyz, dtype=float).reshape(-1, 3),
            [tasks[n].vehicle for n in names],
            np.array([tasks[n].vehicle.body_radius_m for n in names], dtype=float),
            checked,
            dock,
        )

    def pairs(self, radius_m: float) -> tuple[np.ndarray, np.ndarray]:
        """Index pairs (i < j) within ``radius_m`` horizontally, dock pairs left out, m."""
        from scipy.spatial import cKDTree

        if len(self.names) < 2 or radius_m <= 0.0:
            return np.zeros(0, dtype=int), np.zeros(0, dtype=int)
        pairs = cKDTree(self.xyz[:, :2]).query_pairs(radius_m, output_type="ndarray")
        i, j = pairs[:, 0], pairs[:, 1]
        if self.dock:
            keep = np.array([(a, b) not in self.dock and (b, a) not in self.dock for a, b in pairs], dtype=bool)
            i, j = i[keep], j[keep]
        return i, j


class _CutTables:
    """The scenario's cut-off tables (``cutoff_table`` at ``limits.authority_fraction``) of every
    ordered pair of vehicle types, as rows of one array (:func:`stack_tables`)."""

    def __init__(self, scenario: Scenario, sets: list[_Points]):
        from proxplan.costmaps import effects_key

        lim = scenario.limits
        self.types = list(dict.fromkeys(v for pts in sets for v in pts.vehicles))
        self.type_of = {v: k for k, v in enumerate(self.types)}
        fx = effects_key(getattr(scenario, "effects", ()))
        tabs = [
            bracket_table(
                cutoff_table(
                    s,
                    t,
                    level=lim.authority_fraction,
                    rule=lim.invalid_zone_rule,
                    field_form=scenario.field_form,
                    effects=fx,
                )
            )
            for s in self.types
            for t in self.types
        ]
        self.cut = stack_tables([t[0] for t in tabs])
        self.step = np.array([t[1] for t in tabs], dtype=float)
        self.reach_m = float(self.cut.max(initial=0.0))

    def radius(self, pts: _Points, source: np.ndarray, target: np.ndarray, dz_m: np.ndarray) -> np.ndarray:
        """r_cut (m) of ``source`` (indices into ``pts``) on ``target`` at ``dz_m`` below it."""
        t = np.array([self.type_of[v] for v in pts.vehicles], dtype=int)
        return cutoff_lookup(self.cut, self.step, t[source] * len(self.types) + t[target], dz_m)


def _first(idx: np.ndarray, key: np.ndarray, then: np.ndarray) -> int:
    """The entry of ``idx`` (indices into ``key`` and ``then``) with the smallest ``key``, then ``then``."""
    return int(idx[np.lexsort((then[idx], key[idx]))][0])


def _too_close(pts: _Points, min_separation_m: float, where: str) -> None:
    i, j = pts.pairs(max(min_separation_m, 2.0 * float(pts.radius.max(initial=0.0))))
    d = np.linalg.norm(pts.xyz[i] - pts.xyz[j], axis=1)
    need = np.maximum(min_separation_m, pts.radius[i] + pts.radius[j])
    bad = np.flatnonzero(d < need)
    if bad.size:
        k = _first(bad, i, j)
        a, b = pts.names[i[k]], pts.names[j[k]]
        raise UserError(
            f"{where}vehicles.{a}.{pts.kind} and vehicles.{b}.{pts.kind}: {d[k]:.3f} m apart; expected at least "
            f"{need[k]:.3f} m (limits.min_separation_m or the two body radii)"
        )


def _goal_in_cutoff(goals: _Points, tables: _CutTables, level: float, where: str) -> None:
    i, j = goals.pairs(tables.reach_m)
    xyz = goals.xyz
    hi = np.where(xyz[i, 2] >= xyz[j, 2], i, j)  # source above, target below
    lo = np.where(hi == i, j, i)
    dz = xyz[hi, 2] - xyz[lo, 2]
    r = np.linalg.norm(xyz[hi, :2] - xyz[lo, :2], axis=1)
    rc = tables.radius(goals, hi, lo, dz)
    bad = np.flatnonzero((dz > 0.0) & (r < rc))
    if bad.size:
        k = _first(bad, lo, hi)  # the first target below, then the first source above it
        t_name, s_name = goals.names[lo[k]], goals.names[hi[k]]
        raise UserError(
            f"{where}vehicles.{t_name}.goal is inside the downwash cut-off of vehicles.{s_name}.goal "
            f"({r[k]:.3f} m to the side, {dz[k]:.3f} m below; expected at least {rc[k]:.3f} m to the side at "
            f"authority level {level:g})"
        )


def _first_conflict(scenario: Scenario, pts: _Points, tables: _CutTables, mode: str) -> None:
    """InfeasibleError for the first checked vehicle of ``pts`` breaking one of ``mode``'s pair rules."""
    if mode not in MODES:
        raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
    r_max = float(pts.radius.max(initial=0.0))
    reach = max(scenario.limits.min_separation_m, 2.0 * r_max)  # separation and ellipsoid radius, m
    if mode == "downwash":
        reach = max(reach, tables.reach_m)
    a, b = pts.pairs(reach + 1e-6)
    me, other = np.concatenate([a, b]), np.concatenate([b, a])  # every pair both ways
    keep = pts.checked[me]
    me, other = me[keep], other[keep]
    rel = pts.xyz[me] - pts.xyz[other]
    r2 = rel[:, 0] * rel[:, 0] + rel[:, 1] * rel[:, 1]
    dz = rel[:, 2]
    sep = np.maximum(scenario.limits.min_separation_m, pts.radius[me] + pts.radius[other])
    ell2 = np.full(me.size, np.nan)
    rc = np.zeros(me.size)
    if mode == "ellipsoid":
        ell2 = (pts.radius[me] + pts.radius[other]) ** 2
    elif mode == "downwash":  # the other's table on me when it is above, mine on it when it is below
        up = dz > 0.0
        rc = tables.radius(pts, np.where(up, me, other), np.where(up, other, me), dz)
    kind = rule_kind(r2, dz, np.ones(me.size, dtype=bool), sep * sep, ell2, rc)
    hit = np.flatnonzero(kind >= 0)
    if hit.size == 0:
        return
    bad_static = _static_conflicts(scenario, pts, np.unique(me[hit]))
    hit = hit[~np.isin(me[hit], bad_static)]  # those the planner names ("workspace", "obstacle[i]")
    if hit.size == 0:
        return
    k = _first(hit, me, other)  # first vehicle, then its first other in file order
    name, o = pts.names[me[k]], pts.names[other[k]]
    what = ("separation from", "ellipsoid of" if mode == "ellipsoid" else "downwash of", "downwash on")[kind[k]]
    bad = f"{what} {o}"
    when = "at t = 0" if pts.kind == "start" else "while holding it"
    raise InfeasibleError(
        name, bad, f"vehicle {name!r}: its {pts.kind} {np.round(pts.xyz[me[k]], 4).tolist()} violates '{bad}' {when}"
    )


def _static_conflicts(scenario: Scenario, pts: _Points, idx: np.ndarray) -> np.ndarray:
    """The vehicles among ``idx`` whose point is outside the workspace or in an obstacle (the
    checker's static rules, per vehicle type)."""
    out = []
    for v in dict.fromkeys(pts.vehicles[i] for i in idx):
        mine = np.array([i for i in idx if pts.vehicles[i] == v], dtype=int)
        batch = BatchChecker.from_checker(build_checker(scenario, pts.names[mine[0]], [], tube=False))
        static, _ = batch.conflict_codes(pts.xyz[mine], np.zeros(mine.size))
        out.append(mine[static >= 0])
    return np.concatenate(out) if out else np.zeros(0, dtype=int)


def check_goal_loops(scenario: Scenario) -> None:
    """InfeasibleError for the first vehicle (file order) whose closed loop is not damped where it
    holds for ever, its final position in the jets of the others at theirs
    (:func:`proxplan.verify.jet_loop.hold_poles`: the rightmost pole of its controller's loop
    linearised there has a real part >= 0, so it oscillates there however it is planned; the
    margin is minus that real part). Sources: every other vehicle above it whose jet can reach it
    (:func:`proxplan.verify.reach.usage_grid`'s reach of the pair)."""
    from proxplan.verify import hold_poles

    final = {n: np.asarray(scenario.final_position_m(n), dtype=float) for n in scenario.vehicles}
    opts = scenario.model_options
    effects = tuple(scenario.effects)
    where = f"{scenario.source_path}: " if scenario.source_path else ""
    for name, task in scenario.vehicles.items():
        p = final[name]
        above = [
            o for o, q in final.items()
            if o != name and q[2] - p[2] > 1e-6 and _in_jet(scenario.vehicles[o].vehicle, q, p)
        ]  # fmt: skip
        if not above:
            continue
        sources = [(scenario.vehicles[o].vehicle, final[o]) for o in above]
        growth, freq = hold_poles(task.vehicle, p, sources, opts, effects)
        if growth < 0.0:
            continue
        source = min(above, key=lambda o: float(np.hypot(*(final[o] - p)[:2])) + abs(float(final[o][2] - p[2])))
        what = "dock" if task.dock_with is not None else "hover point" if task.hover else "goal"
        raise InfeasibleError(
            name,
            f"jet loop of {source}",
            f"{where}vehicle {name!r}: its closed loop is not damped where it holds at its {what} "
            f"{np.round(p, 3).tolist()} in the jet of {source!r}: rightmost pole {growth:+.3f} 1/s at {freq:.2f} Hz "
            f"(margin {-growth:+.3f} 1/s; the jet's restoring torque reaches the vehicle's tilt through its "
            "attitude loop's lag and undamps the position loop): it would oscillate there however it is planned; "
            "hold it farther below or aside of that vehicle, or retune its attitude loop",
            details={
                "kind": "jet-loop",
                "vehicle": name,
                "other_vehicle": source,
                "position_m": np.round(p, 4).tolist(),
                "growth_ps": growth,
                "frequency_hz": freq,
                "margin_ps": -growth,
            },
        )


def _in_jet(source: Vehicle, p_source: np.ndarray, p_target: np.ndarray) -> bool:
    """Whether ``p_target`` (3,) is within the horizontal reach of ``source``'s jet from
    ``p_source`` (3,), m: the Gaussian profile (S0-2) at the offset's distance below the virtual
    origin down to exp(-36) of the centreline, plus the source's body twice (the target's disks)."""
    dz = float(p_source[2] - p_target[2])
    width = max(dz - source.downwash.z0_m, 0.0) + source.size_m
    reach = 6.0 * width / np.sqrt(source.downwash.c_rad) + 2.0 * source.body_radius_m
    return float(np.hypot(*(p_target - p_source)[:2])) <= reach
