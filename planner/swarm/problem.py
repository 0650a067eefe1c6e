"""A swarm scenario as the coordination layer sees it: agents (vehicles), their types, starts and
goals, kinematic limits, pairwise keep-outs and the static free space.

World frame, z up, m. Agents are indexed in the scenario's file order; ``type_index`` maps each
agent to its vehicle type (one :class:`~proxplan.planner.swarm.keepout.KeepOut` per ordered type
pair). Keep-outs are grown by the tracking tube (while either vehicle moves), by the bounds on the
two vehicles' tracking errors (moving, or held: :func:`swarm_problem`) and by
``GROWTH_M`` (rounding of positions to whole millimetres in the conflict tables); the static free
space is the workspace shrunk, and the obstacles inflated, by the widest body, the tube and the
obstacle margin (:func:`proxplan.planner.checks.constraints.build_checker`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from proxplan.physics import KinematicLimits, Vehicle
from proxplan.planfile import Scenario
from proxplan.planner.swarm.keepout import KeepOut, keepout_for
from proxplan.planner.swarm.memo import MAX_STATIC_ENTRIES, Memo

GROWTH_M = 0.002  # keep-outs grown by this much: positions are compared in whole millimetres, m


@dataclass(frozen=True)
class SwarmProblem:
    """Agents of a swarm scenario (see module). Arrays are indexed by agent."""

    names: tuple[str, ...]
    type_index: np.ndarray  # (A,) int: index into ``vehicles``
    vehicles: tuple[Vehicle, ...]  # one per type
    limits: tuple[KinematicLimits, ...]  # per agent
    starts_m: np.ndarray  # (A, 3) m
    goals_m: np.ndarray  # (A, 3) m
    pinned: np.ndarray  # (A,) bool: hovering vehicles, never moved
    keepouts: dict[tuple[int, int], KeepOut]  # (type a, type b) -> keep-out of d = p_b - p_a
    lo_m: np.ndarray  # (3,) static free box (workspace shrunk by body, tube, margin), m
    hi_m: np.ndarray  # (3,) m
    boxes_m: np.ndarray  # (O, 6) inflated obstacles (min xyz, max xyz), m
    # answers of the single-vehicle searches against an occupancy's content (swarm.memo); a new, empty
    # one for every problem, also one made by dataclasses.replace (a subproblem's agents are numbered anew)
    memo: Memo = field(init=False, default_factory=Memo, compare=False, repr=False)
    # answers about the static free space (segment_free, the wavefront's static grid): they depend on
    # the box, the obstacles and the question only
    static_memo: Memo = field(init=False, default_factory=lambda: Memo(MAX_STATIC_ENTRIES), compare=False, repr=False)

    @property
    def n_agents(self) -> int:
        return len(self.names)

    @property
    def reach_xy_m(self) -> float:
        """Largest horizontal distance at which any pair can conflict while moving, m."""
        return max(k.reach_xy_m for k in self.keepouts.values())

    @property
    def reach_z_m(self) -> float:
        """Largest vertical distance at which any pair can conflict while moving, m."""
        return max(k.reach_z_m for k in self.keepouts.values())

    def common_limits(self, agents) -> KinematicLimits:
        """The element-wise smallest limits of ``agents`` (a synchronous group flies at these)."""
        lims = [self.limits[a] for a in agents]
        return KinematicLimits(
            min(x.max_speed_mps for x in lims), min(x.max_accel_mps2 for x in lims), min(x.max_jerk_mps3 for x in lims)
        )

    def static_free(self, points_m: np.ndarray) -> np.ndarray:
        """(...,) bool: points (..., 3) inside the free box and outside every inflated obstacle."""
        p = np.asarray(points_m, dtype=float)
        ok = np.all((p >= self.lo_m) & (p <= self.hi_m), axis=-1)
        for b in self.boxes_m:
            ok &= ~np.all((p >= b[:3]) & (p <= b[3:]), axis=-1)
        return ok

    def static_free_grid(self, xs_m: np.ndarray, ys_m: np.ndarray, z_m: float) -> np.ndarray:
        """(nx, ny) bool: :meth:`static_free` at the points (xs_m[i], ys_m[j], z_m), computed per axis: the
        free box and the obstacles are axis-aligned boxes, so each test is an outer product of 1-D tests
        (the same comparisons as the point-wise test, without the (nx, ny, 3) array of points)."""

        def inside(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
            in_x = (xs_m >= lo[0]) & (xs_m <= hi[0])
            in_y = (ys_m >= lo[1]) & (ys_m <= hi[1])
            return in_x[:, None] & in_y[None, :] & bool(lo[2] <= z_m <= hi[2])

        ok = inside(self.lo_m, self.hi_m)
        for b in self.boxes_m:
            ok &= ~inside(b[:3], b[3:])
        return ok

    def segment_free(self, p0_m: np.ndarray, p1_m: np.ndarray, step_m: float = 0.02) -> bool:
        """True when the straight segment p0 -> p1 stays in the static free space (every ``step_m``;
        asked again, given back from ``static_memo``)."""
        p0 = np.asarray(p0_m, dtype=float)
        p1 = np.asarray(p1_m, dtype=float)
        return self.static_memo.get(
            ("segment", p0.tobytes(), p1.tobytes(), step_m), lambda: self._segment_free(p0, p1, step_m)
        )

    def _segment_free(self, p0_m: np.ndarray, p1_m: np.ndarray, step_m: float) -> bool:
        n = max(2, int(math.ceil(float(np.linalg.norm(p1_m - p0_m)) / step_m)) + 1)
        s = np.linspace(0.0, 1.0, n)[:, None]
        return bool(self.static_free(p0_m * (1.0 - s) + p1_m * s).all())


def swarm_applicable(scenario: Scenario) -> str | None:
    """None when the swarm layer can plan ``scenario``, else why not (it has no dock approach)."""
    for name, task in scenario.vehicles.items():
        if task.dock_with is not None:
            return f"vehicle {name!r} docks (the swarm layer has no dock approach)"
    return None


def tracking_growth_m(scenario: Scenario, *, held: bool = False) -> dict[str, float]:
    """Per vehicle the bound on the tracking error the verifier will predict for it in any plan
    the swarm layer can time, m (:func:`proxplan.planner.swarm.tracking_bound.tracking_bound_m`: its
    type's moves at its own limits and at every group's common limits, up to the workspace's
    diagonal); ``held``: the bound while it is held, after its last move ended
    (:func:`~proxplan.planner.swarm.tracking_bound.held_bound_m`, at most the other)."""
    from proxplan.planner.swarm.tracking_bound import group_limits, held_bound_m, tracking_bound_m

    bound = held_bound_m if held else tracking_bound_m
    every = [t.kinematic_limits for t in scenario.vehicles.values()]
    longest = float(np.linalg.norm(np.asarray(scenario.workspace_max_m) - np.asarray(scenario.workspace_min_m)))
    out = {}
    for name, task in scenario.vehicles.items():
        if task.hover:  # a hovering vehicle never moves: no tracking error along a reference
            continue
        limits = tuple(group_limits(every, task.kinematic_limits))
        out[name] = bound(task.vehicle, limits, round(longest, 3))
    return out


def swarm_problem(
    scenario: Scenario,
    goals_m: np.ndarray | None = None,
    *,
    deflection_m: Mapping[str, float] | None = None,
    tracking_bound: bool = True,
) -> SwarmProblem:
    """The :class:`SwarmProblem` of ``scenario`` (``goals_m`` (A, 3) overrides the goals, e.g. an
    assignment); hovering vehicles keep their start as goal and are pinned. Each vehicle's tube
    grows by the larger of ``deflection_m`` (m per vehicle name: its predicted deflection in a plan
    made before) and, with ``tracking_bound``, the bound on its predicted tracking error in any plan
    the swarm layer can time (:func:`tracking_growth_m`): as in the verifier a pair's keep-out grows
    by the sum of its two vehicles' growths, moving and at rest (the verifier adds both vehicles'
    predicted deflections at every sample, ``verify.pair_checks.check_pairs``); keep-outs are per pair
    of types, so each type counts with the largest growth of its vehicles
    (:func:`~proxplan.planner.swarm.keepout.keepout_for`).

    At rest the growth is the verifier's at-rest rule (issue 37, round 37Z): the pair's keep-out
    without the tube (the verifier adds ``tracking_margin_m`` only while either vehicle moves), grown
    by the two vehicles' deflections there: ``deflection_m`` (a prediction, which the verifier adds at
    rest too) or, the larger, the bound on the tracking error of a vehicle *held* after its last move
    (``tracking_growth_m(held=True)``, B_held of :mod:`~proxplan.planner.swarm.tracking_bound`), not the
    bound while it moves: two vehicles held at rest are both past the end of their moves."""
    from proxplan.costmaps import effects_key
    from proxplan.planner.checks.constraints import build_checker

    names = tuple(scenario.vehicles)
    vehicles: list[Vehicle] = []
    index: dict[Vehicle, int] = {}
    types = []
    for n in names:
        v = scenario.vehicles[n].vehicle
        if v not in index:
            index[v] = len(vehicles)
            vehicles.append(v)
        types.append(index[v])
    grow = [0.0] * len(vehicles)  # per type: the largest growth of its vehicles' tubes while moving, m
    held = [0.0] * len(vehicles)  # per type: the same while held (at rest), m
    tracking = tracking_growth_m(scenario) if tracking_bound else {}
    tracking_held = tracking_growth_m(scenario, held=True) if tracking_bound else {}
    for n, t in zip(names, types):
        predicted = float((deflection_m or {}).get(n, 0.0))
        grow[t] = max(grow[t], predicted, tracking.get(n, 0.0))
        held[t] = max(held[t], predicted, tracking_held.get(n, 0.0))
    fx = effects_key(getattr(scenario, "effects", ()))
    keep = {
        (ia, ib): keepout_for(
            va,
            vb,
            limits=scenario.limits,
            field_form=scenario.field_form,
            effects=fx,
            sample_m=GROWTH_M,
            deflection_m=grow[ia] + grow[ib],
            rest_deflection_m=held[ia] + held[ib],
        )
        for ia, va in enumerate(vehicles)
        for ib, vb in enumerate(vehicles)
    }
    widest = max(names, key=lambda n: (scenario.vehicles[n].vehicle.body_radius_m, n))
    chk = build_checker(scenario, widest, [], margin_m=float(scenario.limits.tracking_margin_m))
    starts = np.array([scenario.vehicles[n].start_m for n in names], dtype=float)
    if goals_m is None:
        goals = np.array(
            [
                scenario.vehicles[n].goal_m if scenario.vehicles[n].goal_m is not None else scenario.vehicles[n].start_m
                for n in names
            ],
            dtype=float,
        )
    else:
        goals = np.asarray(goals_m, dtype=float)
    return SwarmProblem(
        names=names,
        type_index=np.array(types, dtype=np.int64),
        vehicles=tuple(vehicles),
        limits=tuple(scenario.vehicles[n].kinematic_limits for n in names),
        starts_m=starts,
        goals_m=goals,
        pinned=np.array([bool(scenario.vehicles[n].hover) for n in names]),
        keepouts=keep,
        lo_m=np.asarray(chk.lo, dtype=float),
        hi_m=np.asarray(chk.hi, dtype=float),
        boxes_m=np.asarray(chk.boxes, dtype=float).reshape(-1, 6),
    )
