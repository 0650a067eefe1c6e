"""Constraint checks used by the sampling planner: workspace, obstacles, separation and downwash.

Frames: world z up, positions of centres of mass in m, times in s. A vehicle being planned is
checked against the vehicles planned before it (moving disturbance sources, sampled on a time grid)
and the start positions of those not planned yet.

Modes (``--method``):

``downwash``    separation + the disturbance-cutoff maps of the cost-map issue: target T at
                horizontal distance r and vertical separation dz below source S is invalid when
                r < r_cut_{S->T}(dz) at level ``limits.authority_fraction``
                (``proxplan.costmaps.map_store.pair_maps(S, T).cutoff.r_cut_m``); checked both ways.
``no-downwash`` separation only (baseline).
``ellipsoid``   Crazyswarm-style keep-out ellipsoid: horizontal radius r, vertical radius 3 r, with
                r = sum of the two body radii (arm + propeller radius), scaled to the vehicles' size.

Invalid zone of the model (0 < dz <= 3 L of the source, S0 II-A): ``limits.invalid_zone_rule`` is
passed to the cost map (``CutoffMap.r_cut_m(..., invalid_rule=...)``, documented in
:mod:`proxplan.costmaps.cutoff`): ``conservative`` (default), ``model`` or ``forbid``.
Scalar Python math is used per state because OMPL calls the checker once per state.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Mapping
from dataclasses import dataclass, field, replace
from functools import lru_cache

import numpy as np

from proxplan.physics import VALIDITY_FACTOR_L, Vehicle

MODES = ("downwash", "no-downwash", "ellipsoid")
DZ_STEP_M = 0.02  # resolution of the per-pair cutoff lookup, m
DZ_MAX_M = 6.0  # beyond this vertical separation the cutoff is taken as 0, m


@dataclass(frozen=True)
class CutoffTable:
    """r_cut (m) of one ordered (source -> target) pair on a uniform dz grid ``k * dz_step_m``."""

    source: str
    target: str
    level: float
    dz_step_m: float
    r_cut_m: tuple[float, ...]  # (K,) m; conservative lookup takes the larger bracketing sample
    invalid_dz_m: float  # 3 L of the source, m
    provenance: str  # "proxplan.costmaps.map_store" or "local stand-in"

    def lookup(self, dz_m: float) -> float:
        """Cutoff radius at vertical separation ``dz_m`` (target below > 0), m; 0 when dz <= 0."""
        if dz_m <= 0.0:
            return 0.0
        k = int(dz_m / self.dz_step_m)
        if k + 1 >= len(self.r_cut_m):
            return 0.0
        a, b = self.r_cut_m[k], self.r_cut_m[k + 1]
        return a if a > b else b


def _map_r_cut(
    source: Vehicle, target: Vehicle, dz: np.ndarray, level: float, rule: str, field_form: str | None, effects: tuple
) -> tuple[np.ndarray, str]:
    """r_cut(dz) with the invalid-zone ``rule`` from the cost maps (proxplan.costmaps.map_store); ``effects``
    a :func:`proxplan.costmaps.effects_key` of a calibrated model's effects between vehicles."""
    from proxplan.costmaps import effects_of_key, pair_maps
    from proxplan.physics import ModelOptions

    options = ModelOptions(field_form=field_form) if field_form else ModelOptions()
    maps = pair_maps(source, target, options=options, effects=effects_of_key(effects))
    return np.asarray(
        maps.cutoff.r_cut_m(dz, level=level, invalid_rule=rule), dtype=float
    ), "proxplan.costmaps.map_store"


@lru_cache(maxsize=256)
def cutoff_table(
    source: Vehicle,
    target: Vehicle,
    *,
    level: float,
    rule: str = "conservative",
    field_form: str | None = None,
    effects: tuple = (),
) -> CutoffTable:
    """The per-pair cutoff lookup at authority ``level`` with the invalid-zone ``rule`` applied
    (``effects``: :func:`proxplan.costmaps.effects_key` of the scenario's effects, hashable for the cache)."""
    dz = np.arange(0.0, DZ_MAX_M + DZ_STEP_M, DZ_STEP_M)
    r_cut, provenance = _map_r_cut(source, target, dz, level, rule, field_form, effects)
    r_cut = np.where(dz > 0, np.maximum(r_cut, 0.0), 0.0)
    invalid_dz = VALIDITY_FACTOR_L * source.size_m
    return CutoffTable(
        source.name, target.name, float(level), DZ_STEP_M, tuple(float(v) for v in r_cut), float(invalid_dz), provenance
    )


@dataclass(frozen=True)
class UsageTable:
    """Predicted authority usage of the target at (r, dz) from a source, for the planner's
    objective: the cost map's usage grid (maximised over azimuth, ``CutoffMap.usage``) resampled on
    a regular grid ``usage[k_dz][k_r]`` (steps ``dz_step_m``, ``r_step_m``, m); 0 outside."""

    dz_step_m: float
    r_step_m: float
    usage: tuple[tuple[float, ...], ...]

    def lookup(self, r_m: float, dz_m: float) -> float:
        if dz_m <= 0.0:
            return 0.0
        k = int(dz_m / self.dz_step_m + 0.5)
        j = int(r_m / self.r_step_m + 0.5)
        if k >= len(self.usage) or j >= len(self.usage[0]):
            return 0.0
        return self.usage[k][j]


@lru_cache(maxsize=256)
def usage_table(
    source: Vehicle, target: Vehicle, *, field_form: str | None = None, effects: tuple = ()
) -> UsageTable | None:
    """The :class:`UsageTable` of an ordered pair from the cost maps (``effects`` as in
    :func:`cutoff_table`)."""
    from proxplan.costmaps import effects_of_key, pair_maps
    from proxplan.physics import ModelOptions

    options = ModelOptions(field_form=field_form) if field_form else ModelOptions()
    cmap = pair_maps(source, target, options=options, effects=effects_of_key(effects)).cutoff
    dz = np.arange(0.0, float(cmap.dz_m[-1]) + 1e-9, 0.05)
    r = np.arange(0.0, float(cmap.r_grid_m.max()) + 1e-9, 0.02)
    cols = np.stack(
        [np.interp(r, cmap.r_grid_m[:, k], cmap.usage[:, k], right=0.0) for k in range(cmap.dz_m.size)], axis=1
    )
    grid = np.stack([np.interp(dz, cmap.dz_m, cols[j]) for j in range(r.size)], axis=1)  # (n_dz, n_r)
    grid[0] = 0.0
    return UsageTable(0.05, 0.02, tuple(tuple(float(v) for v in row) for row in grid))


@dataclass
class Track:
    """Another vehicle's motion, sampled every ``dt_s`` from t = 0: ``xyz`` lists of length N, m.

    Before 0 and after the last sample it holds its first/last position. ``until_s`` ends its
    presence (used for the starts of vehicles not planned yet: assumed to leave by then), s.
    """

    name: str
    vehicle: Vehicle
    dt_s: float
    x: list[float]
    y: list[float]
    z: list[float]
    until_s: float = math.inf

    @classmethod
    def static(cls, name: str, vehicle: Vehicle, p_m: np.ndarray, *, until_s: float = math.inf) -> Track:
        return cls(name, vehicle, 1.0, [float(p_m[0])], [float(p_m[1])], [float(p_m[2])], until_s)

    @classmethod
    def from_arrays(cls, name: str, vehicle: Vehicle, dt_s: float, position_m: np.ndarray) -> Track:
        """From positions (N, 3), m, sampled at k * dt_s."""
        p = np.asarray(position_m, dtype=float)
        return cls(name, vehicle, float(dt_s), p[:, 0].tolist(), p[:, 1].tolist(), p[:, 2].tolist())

    @property
    def end_s(self) -> float:
        return (len(self.x) - 1) * self.dt_s

    def moving_at(self, t_s: float, *, rest_speed_mps: float = 0.05) -> bool:
        """Whether the track moves faster than ``rest_speed_mps`` around ``t_s`` (finite difference)."""
        h = 0.5 * self.dt_s
        a, b = self.at(t_s - h), self.at(t_s + h)
        return math.dist(a, b) > rest_speed_mps * 2.0 * h

    def at(self, t_s: float) -> tuple[float, float, float]:
        """Linearly interpolated position at ``t_s``, m."""
        n = len(self.x)
        u = t_s / self.dt_s
        if u <= 0.0 or n == 1:
            return self.x[0], self.y[0], self.z[0]
        k = int(u)
        if k >= n - 1:
            return self.x[-1], self.y[-1], self.z[-1]
        f = u - k
        return (
            self.x[k] + f * (self.x[k + 1] - self.x[k]),
            self.y[k] + f * (self.y[k + 1] - self.y[k]),
            self.z[k] + f * (self.z[k + 1] - self.z[k]),
        )


@dataclass
class PairRule:
    """What the planned vehicle must keep from one other vehicle."""

    track: Track
    separation_m: float
    cut_from_other: CutoffTable | None  # other is the source, planned vehicle the target
    cut_on_other: CutoffTable | None  # planned vehicle is the source, other the target
    ellipsoid_r_m: float | None
    usage_from_other: UsageTable | None = None  # other is the source (objective only)
    margin_m: float = 0.0  # added to the cutoff radius, m
    until_margin_s: float = 0.0  # added to the track's presence, s
    tube_m: float = 0.0  # tracking tube: cut-off radius over dz +- tube, plus tube, m
    deflection_m: float = 0.0  # the part of tube_m that stays at rest (predicted deflections), m

    def without_tube(self) -> PairRule:
        """This rule with the tracking tube taken out of its radii (for a pair at rest); the
        predicted deflections stay (a disturbed vehicle is off its plan at rest too)."""
        drop = self.tube_m - self.deflection_m
        return replace(
            self,
            separation_m=self.separation_m - drop,
            ellipsoid_r_m=None if self.ellipsoid_r_m is None else self.ellipsoid_r_m - drop,
            tube_m=self.deflection_m,
        )

    def cutoff_m(self, table: CutoffTable, dz_m: float) -> float:
        """Cut-off radius at vertical separation ``dz_m`` (> 0), m: the table's largest value over
        dz +- tube (the vehicle may fly that far off its plan), plus margin and tube; 0 where the
        model allows any horizontal distance. The tube is taken at the table's resolution: every
        table step within ceil(tube / dz_step) steps of dz's step counts (conservative for a tube
        that is not a whole number of steps; the same rule as proxplan.planner.checks.validity's
        vectorised tables). Where the tube reaches the other vehicle's level (dz <= tube) the first
        step counts too: at least the separation circle."""
        if dz_m <= 0.0:
            return 0.0
        rc = table.lookup(dz_m)
        if self.tube_m > 0.0:
            step = table.dz_step_m
            k = int(dz_m / step)
            reach = int(math.ceil(self.tube_m / step - 1e-9))
            for j in range(max(k - reach, 0), k + reach + 1):
                rc = max(rc, table.lookup((j + 0.5) * step))
        return rc + self.margin_m + self.tube_m if rc > 0.0 else 0.0


@dataclass
class ConflictChecker:
    """Validity of states (x, y, z, t) of one vehicle; counts rejections per constraint kind."""

    name: str
    lo: tuple[float, float, float]  # workspace minus body margins, m
    hi: tuple[float, float, float]
    boxes: list[tuple[float, float, float, float, float, float]]  # inflated obstacles, m
    rules: list[PairRule]
    rejections: dict[str, int] = field(default_factory=dict)

    def static_conflict(self, x: float, y: float, z: float) -> str | None:
        lo, hi = self.lo, self.hi
        if not (lo[0] <= x <= hi[0] and lo[1] <= y <= hi[1] and lo[2] <= z <= hi[2]):
            return "workspace"
        for i, b in enumerate(self.boxes):
            if b[0] <= x <= b[3] and b[1] <= y <= b[4] and b[2] <= z <= b[5]:
                return f"obstacle[{i}]"
        return None

    def conflict(
        self, x: float, y: float, z: float, t: float, *, exclude: str | None = None, resting: bool = False
    ) -> str | None:
        """The first violated constraint at a state ("workspace", "obstacle[i]", "separation from B",
        "downwash of B", "downwash on B", "ellipsoid of B") or None when valid."""
        c = self.static_conflict(x, y, z)
        if c is not None:
            return c
        for rule in self.rules:
            tr = rule.track
            if t >= tr.until_s + rule.until_margin_s or tr.name == exclude:
                continue
            ox, oy, oz = tr.at(t)
            dx, dy, dz = x - ox, y - oy, z - oz
            r2 = dx * dx + dy * dy
            if resting and rule.tube_m > rule.deflection_m and not tr.moving_at(t):
                rule = rule.without_tube()  # both rest: no tracking tube (as the verifier)
            if r2 + dz * dz < rule.separation_m * rule.separation_m:
                return f"separation from {tr.name}"
            if rule.ellipsoid_r_m is not None:
                re = rule.ellipsoid_r_m
                if r2 / (re * re) + dz * dz / (9.0 * re * re) < 1.0:
                    return f"ellipsoid of {tr.name}"
                continue
            if dz < 0.0 and rule.cut_from_other is not None:
                rc = rule.cutoff_m(rule.cut_from_other, -dz)
                if r2 < rc * rc:
                    return f"downwash of {tr.name}"
            elif dz > 0.0 and rule.cut_on_other is not None:
                rc = rule.cutoff_m(rule.cut_on_other, dz)
                if r2 < rc * rc:
                    return f"downwash on {tr.name}"
        return None

    def predicted_usage(self, x: float, y: float, z: float, t: float) -> float:
        """Sum over the other vehicles above of the map's predicted authority usage at a state
        (a conservative proxy for the combined usage), for the planner's objective, -."""
        total = 0.0
        for rule in self.rules:
            table = rule.usage_from_other
            tr = rule.track
            if table is None or t >= tr.until_s:
                continue
            ox, oy, oz = tr.at(t)
            if oz > z:
                total += table.lookup(math.hypot(x - ox, y - oy), oz - z)
        return total

    def valid(self, x: float, y: float, z: float, t: float) -> bool:
        c = self.conflict(x, y, z, t)
        if c is None:
            return True
        kind = c.split(" ")[0] if not c.startswith("obstacle") else "obstacle"
        key = c if kind in ("separation", "downwash", "ellipsoid") else kind
        self.rejections[key] = self.rejections.get(key, 0) + 1
        return False

    def most_rejected(self) -> str | None:
        """The constraint that rejected most states so far (names the blocking vehicle)."""
        if not self.rejections:
            return None
        return max(self.rejections.items(), key=lambda kv: kv[1])[0]


def build_checker(
    scenario,
    name: str,
    tracks: list[Track],
    *,
    mode: str = "downwash",
    level: float | None = None,
    margin_m: float = 0.0,
    until_margin_s: float = 0.0,
    tube: bool = True,
    extra_tube_m: Mapping[str, float] | None = None,
    no_margin: Collection[str] = (),
) -> ConflictChecker:
    """The checker of vehicle ``name`` against ``tracks`` (other vehicles) for one ``mode``.

    ``level`` is the authority-usage level of the cutoff (default ``limits.authority_fraction``).
    Workspace and obstacles are inflated by the body radius horizontally and by
    ``limits.obstacle_margin_m`` vertically (vehicles are flat). ``margin_m`` (m) is added to the
    separation, cutoff and ellipsoid radii and to the obstacle inflation, ``until_margin_s`` (s)
    to the presence of vehicles not planned yet: the planner searches with small margins so that
    the timed trajectory passes the nominal re-check although both sample the motion differently.
    With ``tube`` (default) the scenario's ``limits.tracking_margin_m`` (the closed-loop tracking
    tube, m) is added to the separation and ellipsoid radii and to the cut-off radius, which is
    also taken as its largest value over dz +- tube (so the invalid zone grows by the tube
    vertically too); ``tube=False`` leaves it out. ``conflict(..., resting=True)`` (the planned
    vehicle holds) leaves it out for tracks that rest too, as the verifier does for pairs at rest.
    ``extra_tube_m`` (m per vehicle name) grows a pair's tube by both vehicles' entries: their
    predicted deflections under the plan's own disturbance (the verifier adds them too).
    ``no_margin``: the tracks (names) whose rules leave ``margin_m`` out (the verifier's rule: pairs a
    planner searches without its margin, :func:`proxplan.planner.sampling.prioritized.margin_free`).
    """
    from proxplan.costmaps import effects_key

    if mode not in MODES:
        raise ValueError(f"mode must be one of {MODES}, got {mode!r}")
    task = scenario.vehicles[name]
    lim = scenario.limits
    rb = task.vehicle.body_radius_m
    mz = lim.obstacle_margin_m
    lo = scenario.workspace_min_m + np.array([rb, rb, mz]) + margin_m
    hi = scenario.workspace_max_m - np.array([rb, rb, mz]) - margin_m
    boxes = []
    for box in scenario.obstacles:
        grow = np.array([rb + lim.obstacle_margin_m, rb + lim.obstacle_margin_m, mz]) + margin_m
        boxes.append(tuple((box.min_m - grow).tolist() + (box.max_m + grow).tolist()))
    level = lim.authority_fraction if level is None else level
    tube_m = float(lim.tracking_margin_m) if tube else 0.0
    rules = []
    extra = extra_tube_m or {}
    for tr in tracks:
        other = tr.vehicle
        deflection_m = extra.get(name, 0.0) + extra.get(tr.name, 0.0) if tube else 0.0
        pair_tube_m = tube_m + deflection_m
        pair_margin_m = 0.0 if tr.name in no_margin else margin_m
        sep = max(lim.min_separation_m, rb + other.body_radius_m) + pair_margin_m + pair_tube_m
        cut_from = cut_on = ell = None
        form, fx = scenario.field_form, effects_key(getattr(scenario, "effects", ()))
        usage_from = usage_table(other, task.vehicle, field_form=form, effects=fx)
        if mode == "downwash":
            cut_from = cutoff_table(
                other, task.vehicle, level=level, rule=lim.invalid_zone_rule, field_form=form, effects=fx
            )
            cut_on = cutoff_table(
                task.vehicle, other, level=level, rule=lim.invalid_zone_rule, field_form=form, effects=fx
            )
        elif mode == "ellipsoid":
            ell = rb + other.body_radius_m + pair_margin_m + pair_tube_m
        rules.append(
            PairRule(
                tr, sep, cut_from, cut_on, ell, usage_from, pair_margin_m, until_margin_s, pair_tube_m, deflection_m
            )
        )
    return ConflictChecker(name, tuple(lo.tolist()), tuple(hi.tolist()), boxes, rules)
