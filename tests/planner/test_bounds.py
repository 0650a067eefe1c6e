"""Certified makespan lower bounds (proxplan.planner.bounds): the 1-D reach from rest against a
brute-force linear programme, the straight bound against Ruckig and the tabulated bound, the window
bound against the analytic geodesic round one wall with one gap, the packing number against a
constructed packing, and every bound at most the makespan of plans that pass ``verify``."""

from __future__ import annotations

import math

import numpy as np
import pytest

from proxplan.physics import KinematicLimits
from proxplan.planfile import scenario_from_dict
from proxplan.planner import bounds
from proxplan.planner.formations import LAYOUTS, random_formation
from proxplan.planner.sampling.ordering import lower_bound_makespan_s, unobstructed_time_s
from proxplan.planner.timing.durations import min_segment_duration_s

LIMITS = KinematicLimits(2.0, 4.0, 16.0)  # the built-in types' limits, m/s, m/s^2, m/s^3


def _lp_reach_m(t_end_s: float, lim: KinematicLimits, n: int = 400) -> float:
    """Greatest x(t_end) from rest over piecewise-constant jerks on n steps, speed and acceleration
    bounded at the steps' ends (a brute-force linear programme, HiGHS)."""
    from scipy.optimize import linprog

    h = t_end_s / n
    # state after k steps is linear in the jerks u_0..u_{k-1}: a_k = h sum u, v_k, x_k likewise
    k = np.arange(1, n + 1)[:, None]
    i = np.arange(n)[None, :]
    m = np.clip(k - i, 0, None).astype(float)  # steps since jerk i began (0: not begun)
    on = m > 0
    a_row = np.where(on, h, 0.0)
    v_row = np.where(on, h * h * (m - 0.5), 0.0)
    x_row = np.where(on, h**3 * ((m - 0.5) ** 2 / 2 + 1 / 24), 0.0)
    rows = np.vstack([v_row, -v_row, a_row, -a_row])
    rhs = np.concatenate([np.full(n, lim.max_speed_mps)] * 2 + [np.full(n, lim.max_accel_mps2)] * 2)
    res = linprog(-x_row[-1], A_ub=rows, b_ub=rhs, bounds=[(-lim.max_jerk_mps3, lim.max_jerk_mps3)] * n, method="highs")
    assert res.status == 0
    return float(-res.fun)


@pytest.mark.parametrize("t_end_s", [0.2, 0.6, 1.3])
def test_reach_from_rest_is_the_linear_programme_optimum(t_end_s):
    """The tabulated reach is the greatest distance: a brute-force LP over discretised jerks gets
    within 1 % of it and not beyond it (by more than the discretisation's 0.5 %), and the reach time of
    the LP's distance is at most the LP's time."""
    reach = bounds._reach_table(2.0, 4.0, 16.0)
    x_tab, t_c, x_c = reach
    x_bound = (
        float(np.interp(t_end_s, np.arange(x_tab.size) * bounds.REACH_STEP_S, x_tab))
        if t_end_s <= t_c
        else x_c + 2.0 * (t_end_s - t_c)
    )
    x_lp = _lp_reach_m(t_end_s, LIMITS)
    assert 0.99 * x_bound <= x_lp <= 1.005 * x_bound
    assert bounds.rest_to_free_time_s(0.995 * x_lp, LIMITS) <= t_end_s


@pytest.mark.parametrize("distance_m", [0.05, 0.4, 1.0, 3.7, 8.0])
def test_straight_bound_is_ruckigs_optimum_below_the_table(distance_m):
    """At most the tabulated duration (which rounds up), at least twice the reach of half the distance."""
    t = bounds.straight_time_s(distance_m, LIMITS)
    assert t <= min_segment_duration_s(distance_m, LIMITS)
    assert t >= 2.0 * bounds.rest_to_free_time_s(distance_m / 2.0, LIMITS)
    assert min_segment_duration_s(distance_m, LIMITS) - t < 0.01 + 0.001 * t


def test_no_obstacle_gives_the_straight_line_bound():
    """grid-16 and circle-16 have no obstacle: the certified bound is the largest straight time,
    within 0.2 % (+ the table's centimetre) below the tabulated ``lower_bound_makespan_s``."""
    for layout in ("grid", "circle"):
        sc = scenario_from_dict(LAYOUTS[layout](16))
        b = bounds.certified_bound(sc)
        assert b.bound_s == b.straight_s == b.obstacle_s and b.throughput_s == 0.0
        assert b.bound_s <= lower_bound_makespan_s(sc) <= b.bound_s * 1.002 + 0.006
        setter = b.setter.split(" ")[0]
        assert unobstructed_time_s(sc, setter) == max(unobstructed_time_s(sc, n) for n in sc.vehicles)


def _wall_doc(start, goal, *, gap_lo=0.5, gap_hi=1.3, thick=0.1, speed=None):
    """One vehicle, a wall x in [-thick, thick], full height, with a gap y in [gap_lo, gap_hi]."""
    v = {"type": "crazyflie-2.1", "start": list(start), "goal": list(goal)}
    if speed is not None:
        v.update(max_speed_mps=speed[0], max_accel_mps2=speed[1], max_jerk_mps3=speed[2])
    return {
        "name": "wall",
        "workspace": {"min": [-3.0, -3.0, 0.0], "max": [3.0, 3.0, 2.0]},
        "obstacles": [
            {"name": "south", "min": [-thick, -3.0, 0.0], "max": [thick, gap_lo, 2.0]},
            {"name": "north", "min": [-thick, gap_hi, 0.0], "max": [thick, 3.0, 2.0]},
        ],
        "limits": {"authority_fraction": 0.1, "min_separation_m": 0.25},
        "vehicles": {"a": v},
    }


def test_window_bound_is_the_geodesic_round_one_wall():
    """Start (-2, -1, 1), goal (2, -1, 1), gap y in [0.5, 1.3], wall 0.2 m thick: the shortest route of
    the centre (verify's obstacles: the gap narrowed by the body radius 0.069 m) goes to the gap's
    corner (-0.1, 0.569), along it, and down to the goal: 2 sqrt(1.9^2 + 1.569^2) + 0.2 m. At 0.3 m/s,
    30 m/s^2, 500 m/s^3 (speed dominates) the bound is at least that length over the speed less the
    cells' slack, at most the rest-to-rest time along that route, and above the straight line's time."""
    v = 0.3
    sc = scenario_from_dict(_wall_doc((-2.0, -1.0, 1.0), (2.0, -1.0, 1.0), speed=(v, 30.0, 500.0)))
    lim = sc.vehicles["a"].kinematic_limits
    leg = math.hypot(1.9, 1.5 + 0.069)
    geodesic = 2.0 * leg + 0.2
    b = bounds.certified_bound(sc)
    slack = 2.0 * bounds.window(sc, 0, -0.1, 0.069).half_diag_m / v
    route = 2.0 * bounds.straight_time_s(leg, lim) + bounds.straight_time_s(0.2, lim)
    assert geodesic / v - slack <= b.obstacle_s <= route
    assert b.obstacle_s > b.straight_s + 1.0
    assert "obstacles[0]" in b.setter or "obstacles[1]" in b.setter


def test_window_bound_never_exceeds_a_brute_force_route_through_the_gap():
    """At the built-in limits, any route through the gap, timed rest to rest by Ruckig through two
    points of the gap (a grid of heights), is no faster than the bound (stopping at the corners, the best
    takes 1.6x the bound: an upper check only)."""
    sc = scenario_from_dict(_wall_doc((-1.5, -0.8, 1.0), (1.2, 0.2, 1.0)))
    b = bounds.certified_bound(sc)
    best = math.inf
    for y in np.linspace(0.569, 1.231, 12):
        for z in np.linspace(0.2, 1.8, 5):
            p = [np.array([-1.5, -0.8, 1.0]), np.array([-0.1, y, z]), np.array([0.1, y, z]), np.array([1.2, 0.2, 1.0])]
            best = min(
                best, sum(bounds.straight_time_s(float(np.linalg.norm(q - p_)), LIMITS) for p_, q in zip(p, p[1:]))
            )
    assert b.obstacle_s > b.straight_s
    assert b.obstacle_s <= best


def test_packing_number_holds_a_constructed_packing_and_the_tunnel_count():
    """A 1 m deep slab of cross-section 0.5 x 0.5 m: a cubic lattice at 0.25 m spacing (3 x 3 x 5 =
    45 points) fits, so the bound must be at least 45; and a 0.1 x 0.1 m tunnel cannot hold more
    than floor(1 / sqrt(0.25^2 - 0.1^2 - 0.1^2)) + 1 = 5 points at 0.25 m (its diameter rule)."""
    free = np.ones((20, 20), dtype=bool)
    assert bounds.packing_number(free, (0.025, 0.025), 1.0, 0.25) >= 45
    tunnel = np.ones((4, 4), dtype=bool)
    assert bounds.packing_number(tunnel, (0.025, 0.025), 1.0, 0.25) == 5


def _planned_makespan(sc, method):
    from proxplan.planner import plan_scenario
    from proxplan.planner.timing.plan_grid import moving_end_s
    from proxplan.verify import verify_plan

    plan = plan_scenario(sc, method=method, seed=0)
    assert verify_plan(plan, sc) == []
    return moving_end_s(plan)


@pytest.mark.parametrize(
    ("doc", "detour"),
    [
        (_wall_doc((-1.5, -0.8, 1.0), (1.2, 0.2, 1.0)), True),
        (_wall_doc((-1.2, 2.4, 0.5), (1.0, 2.2, 1.6)), True),
        (LAYOUTS["corridor"](4), False),
        (LAYOUTS["pillar"](4), False),
        (random_formation(6, seed=3), False),
        (random_formation(6, seed=5), False),
    ],
    ids=["wall-1", "wall-2", "corridor-4", "pillar-4", "random-6-s3", "random-6-s5"],
)
def test_bound_at_most_the_makespan_of_verified_plans(doc, detour):
    """Seeded scenarios with obstacles: the sampling planner's plan passes verify and its makespan
    (the sample after the last moving one) is at least the bound; on the two walls the route round
    the wall sets it (above the straight line's time)."""
    sc = scenario_from_dict(doc)
    b = bounds.certified_bound(sc)
    assert b.bound_s >= b.straight_s > 0.0
    assert (b.obstacle_s > b.straight_s) == detour
    assert _planned_makespan(sc, "sampling") >= b.bound_s


def test_window_bound_flies_over_a_low_wall():
    """A wall 1 m high across the whole 2 m high workspace (no gap): from (-1, 0, 0.5) to (1, 0, 0.5)
    the centre must rise above the wall's top (the verifier's obstacle test holds while the centre's
    z is within the box's z range), so the route is 2 sqrt(0.9^2 + 0.5^2) + 0.2 m long; at 1.0 m above
    the wall top the straight line is free and the bound is the straight line's time."""
    v = 0.3
    doc = _wall_doc((-1.0, 0.0, 0.5), (1.0, 0.0, 0.5), speed=(v, 30.0, 500.0))
    doc["obstacles"] = [{"name": "low", "min": [-0.1, -3.0, 0.0], "max": [0.1, 3.0, 1.0]}]
    sc = scenario_from_dict(doc)
    lim = sc.vehicles["a"].kinematic_limits
    leg = math.hypot(0.9, 0.5)
    b = bounds.certified_bound(sc)
    slack = 2.0 * bounds.window(sc, 0, -0.1, 0.069).half_diag_m / v
    route = 2.0 * bounds.straight_time_s(leg, lim) + bounds.straight_time_s(0.2, lim)
    assert (2.0 * leg + 0.2) / v - slack <= b.obstacle_s <= route
    doc["vehicles"]["a"].update(start=[-1.0, 0.0, 1.5], goal=[1.0, 0.0, 1.5])
    high = bounds.certified_bound(scenario_from_dict(doc))
    assert high.obstacle_s == high.straight_s
