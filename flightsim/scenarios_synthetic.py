"""Simple synthetic flights built without the planner (plan arrays for :func:`simulate_plan`).

All positions world frame (z up), m; times s. Trajectories are smooth (minimum-jerk quintic
segments: zero velocity and acceleration at both ends) and sampled every ``dt_s``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from proxplan.physics import BUILTIN_VEHICLES
from proxplan.planfile import Plan, VehicleTrajectory


def _min_jerk(p0: np.ndarray, p1: np.ndarray, t_s: np.ndarray, t0_s: float, t1_s: float):
    """Quintic rest-to-rest segment p0 -> p1 over [t0, t1]; position, velocity, acceleration (N, 3)."""
    T = t1_s - t0_s
    s = np.clip((t_s - t0_s) / T, 0.0, 1.0)
    inside = ((t_s > t0_s) & (t_s < t1_s)).astype(float)
    h = 10 * s**3 - 15 * s**4 + 6 * s**5
    hd = (30 * s**2 - 60 * s**3 + 30 * s**4) / T * inside
    hdd = (60 * s - 180 * s**2 + 120 * s**3) / T**2 * inside
    d = (p1 - p0)[None, :]
    return p0[None, :] + h[:, None] * d, hd[:, None] * d, hdd[:, None] * d


def waypoint_trajectory(
    name: str, type_name: str, waypoints_m: ArrayLike, times_s: ArrayLike, *, dt_s: float = 0.02
) -> VehicleTrajectory:
    """Rest-to-rest minimum-jerk segments through ``waypoints_m`` (K, 3) reached at ``times_s`` (K,)."""
    wp = np.asarray(waypoints_m, dtype=float)
    ts = np.asarray(times_s, dtype=float)
    t = np.arange(0.0, ts[-1] + 0.5 * dt_s, dt_s)
    pos = np.repeat(wp[:1], t.size, axis=0)
    vel = np.zeros_like(pos)
    acc = np.zeros_like(pos)
    for k in range(len(wp) - 1):
        p, v, a = _min_jerk(wp[k], wp[k + 1], t, ts[k], ts[k + 1])
        mask = t >= ts[k]
        pos[mask] = p[mask]
        vel[mask] = v[mask]
        acc[mask] = a[mask]
    return VehicleTrajectory(name, type_name, BUILTIN_VEHICLES[type_name], t, pos, vel, acc)


def _plan(name: str, trajs: Sequence[VehicleTrajectory], dt_s: float) -> Plan:
    return Plan(name, dt_s, {t.name: t for t in trajs}, method="synthetic")


def hover_stack_plan(
    *,
    top_type: str = "crazyflie-2.1",
    bottom_type: str = "crazyflie-parrot",
    separation_m: float = 1.5,
    bottom_position_m: Sequence[float] = (0.0, 0.0, 1.0),
    horizontal_offset_m: Sequence[float] = (0.0, 0.0),
    duration_s: float = 5.0,
    dt_s: float = 0.02,
) -> Plan:
    """Two vehicles hovering still, ``top`` ``separation_m`` above ``bottom`` (plus a horizontal offset)."""
    b = np.asarray(bottom_position_m, dtype=float)
    top = b + np.array([-horizontal_offset_m[0], -horizontal_offset_m[1], separation_m])
    return _plan(
        "hover-stack",
        [
            waypoint_trajectory("top", top_type, [top, top], [0.0, duration_s], dt_s=dt_s),
            waypoint_trajectory("bottom", bottom_type, [b, b], [0.0, duration_s], dt_s=dt_s),
        ],
        dt_s,
    )


def single_hover_plan(
    *,
    type_name: str = "crazyflie-2.1",
    position_m: Sequence[float] = (0.0, 0.0, 1.0),
    duration_s: float = 5.0,
    dt_s: float = 0.02,
) -> Plan:
    """One vehicle hovering alone at ``position_m`` (use a low z for ground effect)."""
    p = np.asarray(position_m, dtype=float)
    return _plan("single-hover", [waypoint_trajectory("solo", type_name, [p, p], [0.0, duration_s], dt_s=dt_s)], dt_s)


def takeoff_hover_plan(
    *,
    type_name: str = "crazyflie-2.1",
    xy_m: Sequence[float] = (0.0, 0.0),
    low_z_m: float = 0.05,
    high_z_m: float = 1.0,
    climb_s: float = 3.0,
    hold_s: float = 2.0,
    dt_s: float = 0.02,
) -> Plan:
    """Hover near the ground, climb to ``high_z_m``, hover, descend again (ground effect sweeps)."""
    lo = np.array([xy_m[0], xy_m[1], low_z_m])
    hi = np.array([xy_m[0], xy_m[1], high_z_m])
    times = np.cumsum([0.0, hold_s, climb_s, hold_s, climb_s, hold_s])
    traj = waypoint_trajectory("solo", type_name, [lo, lo, hi, hi, lo, lo], times, dt_s=dt_s)
    return _plan("takeoff-hover", [traj], dt_s)


def swap_plan(
    *,
    top_type: str = "crazyflie-2.1",
    bottom_type: str = "crazyflie-parrot",
    vertical_gap_m: float = 0.3,
    radius_m: float = 0.25,
    swap_s: float = 3.0,
    n_swaps: int = 4,
    centre_m: Sequence[float] = (0.0, 0.0, 0.8),
    hold_s: float = 1.0,
    dt_s: float = 0.02,
    cross_offset_m: float = 0.0,
) -> Plan:
    """Neural-Swarm-like swaps: both vehicles on a circle of ``radius_m`` at opposite sides,
    ``vertical_gap_m`` apart, swap sides in ``swap_s`` along straight chords, crossing above each
    other at the centre (``cross_offset_m`` apart sideways, m: the bottom chord is shifted along y,
    so the jet's roll torque is exercised as on real swaps, which never cross exactly on axis);
    repeated ``n_swaps`` times with ``hold_s`` pauses."""
    c = np.asarray(centre_m, dtype=float)
    a = c + np.array([radius_m, 0.0, 0.5 * vertical_gap_m])
    b = c + np.array([-radius_m, 0.0, 0.5 * vertical_gap_m])
    dz = np.array([0.0, -cross_offset_m, vertical_gap_m])
    top_wp, bot_wp, times = [a, a], [b - dz, b - dz], [0.0, hold_s]  # leading pause
    t = hold_s
    for k in range(n_swaps):
        top_to, bot_to = (b, a - dz) if k % 2 == 0 else (a, b - dz)
        t += swap_s
        top_wp.append(top_to)
        bot_wp.append(bot_to)
        times.append(t)
        t += hold_s
        top_wp.append(top_to)
        bot_wp.append(bot_to)
        times.append(t)
    return _plan(
        "swap",
        [
            waypoint_trajectory("top", top_type, top_wp, times, dt_s=dt_s),
            waypoint_trajectory("bottom", bottom_type, bot_wp, times, dt_s=dt_s),
        ],
        dt_s,
    )


def battery_swap_plans(
    *,
    carrier_type: str = "large-quad",
    shuttle_type: str = "small-quad",
    carrier_m: Sequence[float] = (0.0, 0.0, 1.5),
    shuttle_start_m: Sequence[float] = (2.0, 1.0, 0.6),
    dock_offset_m: Sequence[float] = (0.0, 0.0, 0.3),
    duration_s: float = 8.0,
    approach_height_m: float = 1.2,
    final_descent_s: float = 3.0,
    dt_s: float = 0.02,
) -> dict[str, Plan]:
    """The battery-swap scenario (scenarios/battery_swap.yaml) flown two ways, same duration:
    ``straight``: the shuttle flies a straight line from its start to the dock;
    ``staged``: it climbs beside the carrier to ``approach_height_m`` above the dock, moves over it,
    and descends slowly (``final_descent_s``) onto the dock so the carrier's disturbance ramps gently.
    """
    c = np.asarray(carrier_m, dtype=float)
    s0 = np.asarray(shuttle_start_m, dtype=float)
    dock = c + np.asarray(dock_offset_m, dtype=float)
    carrier = waypoint_trajectory("carrier", carrier_type, [c, c], [0.0, duration_s], dt_s=dt_s)
    straight = waypoint_trajectory("shuttle", shuttle_type, [s0, dock], [0.0, duration_s], dt_s=dt_s)
    high_side = np.array([s0[0], s0[1], dock[2] + approach_height_m])
    above = dock + np.array([0.0, 0.0, approach_height_m])
    t1 = 0.4 * (duration_s - final_descent_s)
    staged = waypoint_trajectory(
        "shuttle",
        shuttle_type,
        [s0, high_side, above, dock],
        [0.0, t1, duration_s - final_descent_s, duration_s],
        dt_s=dt_s,
    )
    return {
        "straight": _plan("battery-swap-straight", [carrier, straight], dt_s),
        "staged": _plan("battery-swap-staged", [carrier, staged], dt_s),
    }
