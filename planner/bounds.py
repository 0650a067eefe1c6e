"""Certified lower bounds on the makespan of a plan (issue 37, "Must show" and item 6).

Every bound here is a theorem about any trajectory set the pipeline can return and ``verify`` can
pass: each vehicle leaves its start at rest (velocity and acceleration zero), ends at rest at its goal
(or dock point), keeps the norms of its velocity, acceleration and jerk within its task's limits
V (m/s), A (m/s^2), J (m/s^3) (what ``planner/timing`` asks of Ruckig: per-axis limits scaled so that
the norms stay within them, and what ``verify/checks.py`` tests on the norms), keeps its centre out
of the obstacles as the verifier sees them (``verify.checks._check_tasks``: the body disc of radius
r_b horizontally off each box while the centre's z is within the box's z range; the planner inflates
more, so its forbidden set contains this one) and keeps every pair of vehicles at least the
verifier's nominal separation max(min separation, r_a + r_b) apart (m). The makespan is measured
from t = 0, world frame, s. The verifier's tolerances (2 % on speed and acceleration, 5 cm on start and
goal, 1e-6 m on the workspace) are not granted: the bound is on the plan's contract, not on what a
tolerance lets through (obstacles are taken 1e-5 m smaller than the verifier's, for rounding).

The bounds (each proven in its docstring; docs/planner.md, "Stop 54, round 16A"):

- :func:`straight_time_s`: Ruckig's time-optimal rest-to-rest time of the straight distance
  (projection onto the start-goal direction is a 1-D motion within V, A, J);
- :func:`window_time_s`: around obstacles, through the free part of a plane every route must cross
  (a "window"), with a bound on the reach of a 1-D jerk-limited motion from rest (:func:`rest_to_free_time_s`);
- :func:`throughput_time_s`: the vehicles that must cross an obstacle's slab spend a least time
  inside it, and no more than a packing number of them fit in it at once;
- :func:`certified_bound`: the largest of them, with which one set it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from proxplan.physics import KinematicLimits
from proxplan.planfile import Scenario

CELL_M = 0.025  # side of the cells a window is cut into, m (a cell's half-diagonal is the bound's slack: ~0.018 m)
REACH_STEP_S = 5e-4  # time step of the tabulated reach from rest; the bound rounds down by one step, s
OVERLAP_M = 1e-5  # the verifier flags an obstacle overlap above 1e-6 m; forbidden here only beyond this, m
# window_gaps_m re-measures every cell within this of the k-d tree's nearest distance, m (far above the
# tree's rounding, ~1e-16 m, and below the cells' 0.025 m spacing: a few cells per point)
GAP_SLACK_M = 1e-9
# window_gaps_m builds the tree from this many points on (fewer: every cell measured, as one point always
# was; a tree of a 27,000-cell window costs about what 8 points measured against every cell do; timed on
# pillar-64's windows)
GAP_TREE_POINTS = 8
RUCKIG_REL = 1e-6  # Ruckig's optimal duration is taken down by this relative amount (its numerical tolerance), -


@dataclass(frozen=True)
class CertifiedBound:
    """The certified makespan lower bounds of one scenario (s), each over all vehicles.

    ``straight_s``: the largest straight-line rest-to-rest time (the exact optimum, not the
    tabulated one of ``sampling.ordering.lower_bound_makespan_s``); ``obstacle_s``: the largest
    single-vehicle bound around obstacles (>= ``straight_s``); ``throughput_s``: the crossing-rate
    bound (0 without obstacles); ``bound_s``: their maximum; ``setter``: the vehicle or obstacle
    that sets it."""

    straight_s: float
    obstacle_s: float
    throughput_s: float
    bound_s: float
    setter: str


# -- 1-D motion from rest ----------------------------------------------------------------------
@lru_cache(maxsize=64)
def _reach_table(v: float, a: float, j: float) -> tuple[np.ndarray, float, float]:
    """An upper bound on the distance a 1-D motion from rest (x' = x'' = 0) within |x'| <= v,
    |x''| <= a, |x'''| <= j can cover by time t, on a grid t_k = k REACH_STEP_S up to the time t_c at
    which the bound's speed reaches v; (x(t_k) (m), t_c (s), x(t_c) (m)). Beyond t_c it is
    x(t_c) + v (t - t_c).

    Proof: x''(s) <= min(j s, a) (from x''(0) = 0 at jerk <= j), so x'(t) <= g(t), the integral of
    min(j s, a); and x'(t) <= v. So x'(t) <= min(v, g(t)) at every t, and x(t) is at most its
    integral. (The envelope's acceleration jumps from a to 0 where g reaches v, so a real motion
    covers a little less: tested within 1 % of a brute-force optimum.)"""
    if a * a / (2.0 * j) < v:  # the acceleration reaches a before the speed reaches v
        segs = [(a / j, j), ((v - a * a / (2.0 * j)) / a, 0.0)]
    else:
        segs = [(math.sqrt(2.0 * v / j), j)]
    t_c = sum(d for d, _ in segs)
    n = int(math.ceil(t_c / REACH_STEP_S)) + 1
    t = np.arange(n) * REACH_STEP_S
    x = np.zeros(n)
    p = vel = acc = 0.0
    t0 = 0.0
    for dur, jerk in segs:
        s = np.clip(t - t0, 0.0, dur)
        sel = (t >= t0) & (t <= t0 + dur + 1e-15)
        x[sel] = p + vel * s[sel] + acc * s[sel] ** 2 / 2 + jerk * s[sel] ** 3 / 6
        p, vel, acc = (
            p + vel * dur + acc * dur**2 / 2 + jerk * dur**3 / 6,
            vel + acc * dur + jerk * dur**2 / 2,
            acc + jerk * dur,
        )
        t0 += dur
    beyond = t > t_c
    x[beyond] = p + v * (t[beyond] - t_c)
    return x, t_c, p


def rest_to_free_time_s(distance_m, limits: KinematicLimits):
    """The least time (s) in which a 1-D motion from rest within the limits can cover ``distance_m``
    (m; scalar or array), ending at any state, rounded down by one tabulation step (so a lower
    bound). By time reversal it is also the least time to cover the distance and end at rest."""
    x, t_c, x_c = _reach_table(limits.max_speed_mps, limits.max_accel_mps2, limits.max_jerk_mps3)
    d = np.maximum(np.asarray(distance_m, dtype=float), 0.0)
    k = np.searchsorted(x, d, side="left")  # first grid time with x >= d
    early = np.maximum(k - 1, 0) * REACH_STEP_S  # x(t_{k-1}) < d: the motion needs more than t_{k-1}
    late = t_c + (d - x_c) / limits.max_speed_mps
    out = np.where(d <= x_c, early, np.maximum(late, 0.0))
    out = np.where(d <= 0.0, 0.0, out)
    return float(out) if np.ndim(out) == 0 else out


def straight_time_s(distance_m: float, limits: KinematicLimits) -> float:
    """Time-optimal rest-to-rest time over a straight ``distance_m`` (m) within the norm limits, s:
    a lower bound on any rest-to-rest motion between two points that far apart.

    Proof: the projection x(t) = u . p(t) on the unit start-goal direction u is a 1-D motion from
    rest to rest over the distance with |x'| <= |v| <= V, |x''| <= A, |x'''| <= J, and Ruckig's
    1-D duration is that problem's optimum (Berscheid & Kroeger 2021); taken down by its numerical
    tolerance. Also never below twice the reach time of half the distance (tested)."""
    if distance_m <= 0.0:
        return 0.0
    return _ruckig_1d_s(round(float(distance_m), 12), limits) * (1.0 - RUCKIG_REL)


@lru_cache(maxsize=4096)
def _ruckig_1d_s(distance_m: float, limits: KinematicLimits) -> float:
    from ruckig import InputParameter, Ruckig, Trajectory

    otg, inp, traj = Ruckig(1), InputParameter(1), Trajectory(1)
    inp.max_velocity, inp.max_acceleration, inp.max_jerk = (
        [limits.max_speed_mps],
        [limits.max_accel_mps2],
        [limits.max_jerk_mps3],
    )
    inp.current_position, inp.target_position = [0.0], [distance_m]
    otg.calculate(inp, traj)
    return float(traj.duration)


# -- windows: the free part of a plane every route must cross ---------------------------------
@dataclass(frozen=True)
class Window:
    """Cells of an axis-aligned vertical plane (``axis`` 0: x = ``coord_m``, 1: y = ``coord_m``)
    that a centre of a vehicle of body radius ``radius_m`` may occupy: every cell not wholly inside
    an obstacle's forbidden set (so the free set is covered); ``centres_m`` (M, 3), world frame, m;
    ``half_diag_m``: the cells' half-diagonal, m."""

    axis: int
    coord_m: float
    radius_m: float
    centres_m: np.ndarray
    half_diag_m: float
    cell_hz_m: tuple[float, float]  # the cells' sides along the plane's horizontal axis and z, m
    shape: tuple[int, int]
    free: np.ndarray  # (n_h, n_z) bool: the cell grid's free mask (centres_m are its True cells)


def window(
    scenario: Scenario,
    axis: int,
    coord_m: float,
    radius_m: float,
    cell_m: float = CELL_M,
    boxes: tuple[int, ...] | None = None,
) -> Window:
    """The :class:`Window` of the plane x_axis = ``coord_m`` for a body radius ``radius_m`` (m).

    The centre must lie in the workspace (the body disc inside it horizontally, the centre
    vertically: as the verifier) and, for each box whose z range holds the centre, at a horizontal
    distance >= r_b from it; at the plane, a box at distance d_k < r_b along ``axis`` forbids the
    other horizontal coordinate within sqrt(r_b^2 - d_k^2) of its extent (open), z in its z range.
    ``boxes``: only these obstacles (indices; default all), which forbids less."""
    h = 1 - axis
    lo, hi = scenario.workspace_min_m, scenario.workspace_max_m
    h_lo, h_hi = lo[h] + radius_m, hi[h] - radius_m
    z_lo, z_hi = lo[2], hi[2]
    n_h = max(1, int(math.ceil((h_hi - h_lo) / cell_m)))
    n_z = max(1, int(math.ceil((z_hi - z_lo) / cell_m)))
    ch, cz = (h_hi - h_lo) / n_h, (z_hi - z_lo) / n_z
    e_h = h_lo + ch * np.arange(n_h + 1)
    e_z = z_lo + cz * np.arange(n_z + 1)
    free = np.ones((n_h, n_z), dtype=bool)
    r = radius_m - OVERLAP_M
    for i, box in enumerate(scenario.obstacles):
        if boxes is not None and i not in boxes:
            continue
        dk = max(0.0, box.min_m[axis] - coord_m, coord_m - box.max_m[axis])
        if dk >= r:
            continue
        grow = math.sqrt(r * r - dk * dk)
        f_lo, f_hi = box.min_m[h] - grow, box.max_m[h] + grow  # open interval
        in_h = (e_h[:-1] > f_lo) & (e_h[1:] < f_hi)
        in_z = (e_z[:-1] >= box.min_m[2]) & (e_z[1:] <= box.max_m[2])
        free &= ~(in_h[:, None] & in_z[None, :])
    ih, iz = np.nonzero(free)
    centres = np.zeros((ih.size, 3))
    centres[:, axis] = coord_m
    centres[:, h] = h_lo + ch * (ih + 0.5)
    centres[:, 2] = z_lo + cz * (iz + 0.5)
    return Window(axis, coord_m, radius_m, centres, 0.5 * math.hypot(ch, cz), (ch, cz), (n_h, n_z), free)


def reach_through_s(point_m: np.ndarray, win: Window, limits: KinematicLimits) -> float:
    """Least time (s) to go from rest at ``point_m`` (m) to some point of the window's free set (or
    from it to rest at ``point_m``): the minimum over its cells of the reach time of the distance to
    the cell's centre less the half-diagonal (a cell's points are at least that far), i.e. the reach
    time of :func:`window_gaps_m`."""
    if win.centres_m.shape[0] == 0:
        return math.inf
    return float(rest_to_free_time_s(float(window_gaps_m(np.asarray(point_m, dtype=float)[None], win)[0]), limits))


def window_gaps_m(points_m: np.ndarray, win: Window) -> np.ndarray:
    """(P,) m: for each of ``points_m`` (P, 3), the least distance to a centre of the window's free cells
    less the half-diagonal, at least 0 (inf where the window has no free cell): the distance
    :func:`reach_through_s` times, for many points at once. The nearest centres are found by a k-d tree
    (``scipy.spatial.cKDTree``, from :data:`GAP_TREE_POINTS` points on; all within :data:`GAP_SLACK_M` of its
    nearest distance), and the distance is
    computed as one point's would be, ``norm(centres - point)``, over those: the same float as the minimum
    over every cell (round 30B: point by point, 1.2 s of pillar-64 by type's assignment costs)."""
    from scipy.spatial import cKDTree

    pts = np.asarray(points_m, dtype=float).reshape(-1, 3)
    out = np.full(pts.shape[0], math.inf)
    if win.centres_m.shape[0] == 0 or pts.shape[0] == 0:
        return out
    if pts.shape[0] < GAP_TREE_POINTS:  # every cell: cheaper than building the tree
        near: list = [slice(None)] * pts.shape[0]
    else:
        tree = cKDTree(win.centres_m)
        nearest, _ = tree.query(pts)
        near = [np.asarray(i, dtype=int) for i in tree.query_ball_point(pts, r=nearest + GAP_SLACK_M)]
    for p, idx in enumerate(near):
        d = np.linalg.norm(win.centres_m[idx] - pts[p], axis=1)
        out[p] = max(float(d.min()) - win.half_diag_m, 0.0)
    return out


def _end_point(scenario: Scenario, name: str) -> np.ndarray | None:
    task = scenario.vehicles[name]
    if task.hover:
        return None
    end = scenario.dock_geometry(name)[1] if task.dock_with is not None else task.goal_m
    return None if end is None else np.asarray(end, dtype=float)


@dataclass(frozen=True)
class Slab:
    """A box's extent along one horizontal ``axis``: [``lo_m``, ``hi_m``] (m) and its index."""

    box: int
    axis: int
    lo_m: float
    hi_m: float


def slabs(scenario: Scenario) -> list[Slab]:
    """Every box's x and y extents."""
    return [Slab(i, k, float(b.min_m[k]), float(b.max_m[k])) for i, b in enumerate(scenario.obstacles) for k in (0, 1)]


def _crosses(p: np.ndarray, q: np.ndarray, slab: Slab) -> int:
    """+1 when p is below the slab and q above it along its axis, -1 the other way, 0 else."""
    k = slab.axis
    if p[k] < slab.lo_m and q[k] > slab.hi_m:
        return 1
    if p[k] > slab.hi_m and q[k] < slab.lo_m:
        return -1
    return 0


def window_time_s(scenario: Scenario, name: str, slab: Slab, cache: dict | None = None) -> float:
    """Bound (s) on vehicle ``name``'s arrival when its start and goal lie on opposite sides of
    ``slab`` (0 otherwise).

    Proof: say the start is below lo and the goal above hi along the axis. Let t2 be the first time
    the centre is at hi and t1 the last time before t2 it is at lo; p(t1) and p(t2) lie in the
    free sets of those planes (windows W1, W2). The projection on the direction from the start to
    p(t1) is a 1-D motion from rest covering |p(t1) - start|: t1 >= R(|p(t1) - start|) with R the
    reach time (:func:`rest_to_free_time_s`), >= min over W1. Between t1 and t2 the axis coordinate
    goes from lo to hi at speed <= V: t2 - t1 >= (hi - lo) / V. From t2 the vehicle covers
    |goal - p(t2)| and ends at rest: T - t2 >= R(|goal - p(t2)|) (time reversal), >= min over W2.
    Sum. A window cell counts as free unless wholly forbidden, and distances are reduced by the
    cell's half-diagonal, so the minima are lower bounds of the true ones."""
    task = scenario.vehicles[name]
    end = _end_point(scenario, name)
    if end is None:
        return 0.0
    start = np.asarray(task.start_m, dtype=float)
    sign = _crosses(start, end, slab)
    if sign == 0:
        return 0.0
    lim = task.kinematic_limits
    near, far = (slab.lo_m, slab.hi_m) if sign > 0 else (slab.hi_m, slab.lo_m)
    rb = task.body_radius_m
    w1 = _cached_window(scenario, slab.axis, near, rb, cache)
    w2 = _cached_window(scenario, slab.axis, far, rb, cache)
    return reach_through_s(start, w1, lim) + (slab.hi_m - slab.lo_m) / lim.max_speed_mps + reach_through_s(end, w2, lim)


def _cached_window(scenario: Scenario, axis: int, coord: float, rb: float, cache: dict | None) -> Window:
    key = (axis, round(coord, 9), round(rb, 9))
    if cache is None:
        return window(scenario, axis, coord, rb)
    if key not in cache:
        cache[key] = window(scenario, axis, coord, rb)
    return cache[key]


def vehicle_bound_s(scenario: Scenario, name: str, cache: dict | None = None) -> tuple[float, str]:
    """The largest single-vehicle bound of ``name`` (s) and what set it ("straight" or "box i axis k")."""
    end = _end_point(scenario, name)
    if end is None:
        return 0.0, "hover"
    task = scenario.vehicles[name]
    best = (straight_time_s(float(np.linalg.norm(end - task.start_m)), task.kinematic_limits), "straight")
    for slab in slabs(scenario):
        t = window_time_s(scenario, name, slab, cache)
        if t > best[0]:
            best = (t, f"obstacles[{slab.box}] along {'xy'[slab.axis]}")
    return best


# -- throughput through a slab -----------------------------------------------------------------
def packing_number(free: np.ndarray, cell_m: tuple[float, float], depth_m: float, separation_m: float) -> int:
    """At most how many points at mutual distance >= ``separation_m`` (m) fit in the region
    (free cells of a plane's grid, cell sides ``cell_m`` (m)) x [0, ``depth_m``] (m).

    Proof: balls of radius r = separation / 2 round such points are disjoint and lie in the region
    grown by r; that lies in the union of the cells within ceil(r / cell) cells of a free cell (a
    square dilation), times a depth of depth + 2 r. So the count is at most that volume over the
    ball's volume. And when the free cells' bounding box has a diagonal D < separation, two points
    differ across the section by at most D, so along the axis by at least q = sqrt(separation^2 -
    D^2): sorted along it, (count - 1) q <= depth."""
    r = 0.5 * separation_m
    kh, kz = int(math.ceil(r / cell_m[0])), int(math.ceil(r / cell_m[1]))
    n_h, n_z = free.shape
    grown = np.zeros((n_h + 2 * kh, n_z + 2 * kz), dtype=bool)
    for dh in range(2 * kh + 1):
        for dz in range(2 * kz + 1):
            grown[dh : dh + n_h, dz : dz + n_z] |= free
    volume = float(grown.sum()) * cell_m[0] * cell_m[1] * (depth_m + 2 * r)
    count = int(math.floor(volume / (4.0 / 3.0 * math.pi * r**3)))
    ih, iz = np.nonzero(free)
    if ih.size == 0:
        return 0
    diameter = math.hypot((ih.max() - ih.min() + 1) * cell_m[0], (iz.max() - iz.min() + 1) * cell_m[1])
    if diameter < separation_m:  # every pair differs along the axis by >= sqrt(sep^2 - diameter^2)
        count = min(count, int(math.floor(depth_m / math.sqrt(separation_m**2 - diameter**2))) + 1)
    return count


def throughput_time_s(
    scenario: Scenario, slab: Slab, cache: dict | None = None, *, packing: int | None = None
) -> float:
    """Bound (s) from the vehicles that must cross ``slab`` (0 when fewer than two do).

    ``packing``: use this count as K instead of the separation sphere's :func:`packing_number` (a
    caller's hypothesis, e.g. the ceiling of a tighter exclusion; the result is a bound only where
    that count is one).

    Proof: vehicle i crosses the slab (start and goal on opposite sides), so some interval
    [a_i, b_i] has its centre inside the slab all along and crossing it: b_i - a_i >= tau_i =
    depth / V_i; a_i >= e_i (its reach of the entry plane's window from rest, as in
    :func:`window_time_s`) and T - b_i >= l_i (from the exit plane's window to rest). Inside the
    slab every centre lies in the free set of the slab's cross-section (the box's forbidden set is
    the same for every plane of the slab: the boxes that span it, each forbidding at distance 0,
    at the least body radius among the crossers; other boxes are left out, which forbids less), and pairs are at least the least verifier separation
    apart, so at most K (:func:`packing_number`) are inside at once. For any subset S of the
    crossers, all their intervals lie in [min_S e, T - min_S l], so K (T - min_S e - min_S l) >=
    sum_S tau_i. The bound is the largest over the subsets {e_i >= alpha, l_i >= beta}."""
    names = []
    for n, task in scenario.vehicles.items():
        end = _end_point(scenario, n)
        if end is not None and _crosses(np.asarray(task.start_m, dtype=float), end, slab) != 0:
            names.append(n)
    if len(names) < 2:
        return 0.0
    tasks = [scenario.vehicles[n] for n in names]
    rb_min = min(t.body_radius_m for t in tasks)
    sep = min(max(scenario.limits.min_separation_m, a.body_radius_m + b.body_radius_m) for a in tasks for b in tasks)
    depth = slab.hi_m - slab.lo_m
    whole = tuple(
        i
        for i, b in enumerate(scenario.obstacles)
        if b.min_m[slab.axis] <= slab.lo_m and b.max_m[slab.axis] >= slab.hi_m
    )  # the boxes that forbid the same set on every plane of the slab
    if packing is None:
        section = window(scenario, slab.axis, 0.5 * (slab.lo_m + slab.hi_m), rb_min, boxes=whole)
        k_max = packing_number(section.free, section.cell_hz_m, depth, sep - OVERLAP_M)
    else:
        k_max = packing
    if k_max <= 0:
        return math.inf
    e = np.zeros(len(names))
    ell = np.zeros(len(names))
    tau = np.zeros(len(names))
    for i, (n, task) in enumerate(zip(names, tasks)):
        start = np.asarray(task.start_m, dtype=float)
        end = _end_point(scenario, n)
        assert end is not None
        sign = _crosses(start, end, slab)
        near, far = (slab.lo_m, slab.hi_m) if sign > 0 else (slab.hi_m, slab.lo_m)
        lim = task.kinematic_limits
        rb = task.body_radius_m
        e[i] = reach_through_s(start, _cached_window(scenario, slab.axis, near, rb, cache), lim)
        ell[i] = reach_through_s(end, _cached_window(scenario, slab.axis, far, rb, cache), lim)
        tau[i] = depth / lim.max_speed_mps
    best = 0.0
    for alpha in np.unique(e):
        sel_a = e >= alpha
        for beta in np.unique(ell[sel_a]):
            sel = sel_a & (ell >= beta)
            if sel.sum() > k_max:
                best = max(best, float(e[sel].min() + ell[sel].min() + tau[sel].sum() / k_max))
    return best


def certified_bound(scenario: Scenario) -> CertifiedBound:
    """The largest certified bound of ``scenario`` (see module) and which vehicle or obstacle sets it."""
    cache: dict = {}
    straight = 0.0
    obstacle, setter = 0.0, "none"
    for name, task in scenario.vehicles.items():
        end = _end_point(scenario, name)
        if end is None:
            continue
        straight = max(straight, straight_time_s(float(np.linalg.norm(end - task.start_m)), task.kinematic_limits))
        t, how = vehicle_bound_s(scenario, name, cache)
        if t > obstacle:
            obstacle, setter = t, f"{name} ({how})"
    through = 0.0
    for slab in slabs(scenario):
        t = throughput_time_s(scenario, slab, cache)
        if t > through:
            through = t
            if t > obstacle:
                setter = f"throughput of obstacles[{slab.box}] along {'xy'[slab.axis]}"
    return CertifiedBound(straight, obstacle, through, max(obstacle, through), setter)
