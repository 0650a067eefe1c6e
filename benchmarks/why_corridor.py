"""Why corridor's fixed-goal plan is ~4.8x its certified bound, in-process (issue 37; docs/planner.md,
"Stop 54, round 16D").

For ``corridor`` at N vehicles (``planner.formations.corridor``: two groups trade sides through a gap in
a wall at x = 0), with fixed goals:

1. the certified bound (``planner.bounds.certified_bound``) and the swarm layer's plan
   (``plan_scenario(method="swarm", seed=0)``, the bench's child), its stage and wall / CPU s;
2. the plan read back: per vehicle the times it enters and leaves the wall's slab (|x| < half the wall's
   depth), its height and mean speed there, its rest between its first and last motion (before the slab
   and after it); how many are in the slab at once, how long the slab is empty between the first entry
   and the last exit, per height; the median slab entry by start row and arrival by goal row (|x|), and
   whether a block's pitch leaves an aisle between neighbours;
3. the swarm layer's keep-outs: horizontal radius at the same height (dz ~ 0) and at the two groups'
   height difference;
4. the physics behind a bound "through the vertical force": the largest F_z any source exerts on any
   target over a grid of offsets (>= 0 would break the argument) and at dz <= 0;
5. the ceiling of any crossing-rate bound that lets vehicles at one height sit at the verifier's
   separation (the jets act only downwards, so same-height neighbours are never excluded by them): the
   slab's one-height packing K_1, and ``throughput_time_s(..., packing=K_1)``;
6. an estimate (not a plan and not a bound) of a lane flow: each group on its own height, in lanes one
   in-level keep-out apart on its own side of the gap (the two sides the cross-height keep-out apart),
   each vehicle start -> lane mouth -> through -> goal, entering at the earliest time its lane's
   headway (keep-out / V) allows; optimistic (reach from rest to the mouth at any speed, and to rest
   after the exit) and rest-to-rest per leg. Conflicts outside the slab are ignored.

    cd /tmp && python /path/to/benchmarks/why_corridor.py --n 64
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from pathlib import Path

import numpy as np


def _plan(scenario):
    from proxplan.planner import plan_scenario

    wall, cpu = time.perf_counter(), time.process_time()
    plan = plan_scenario(scenario, method="swarm", seed=0)
    return plan, time.perf_counter() - wall, time.process_time() - cpu


def _slab_report(plan, half_depth_m: float) -> list[str]:
    t, dt = plan.t_s, plan.dt_s
    rows, inside = [], []
    for name, tr in plan.vehicles.items():
        p = tr.position_m
        speed = np.linalg.norm(np.gradient(p, dt, axis=0), axis=1)
        g = np.abs(p[:, 0]) < half_depth_m
        moving = np.flatnonzero(speed > 0.02)
        rest = float(np.sum(speed[moving[0] : moving[-1]] <= 0.02) * dt) if moving.size else 0.0
        idx = np.flatnonzero(g)
        if idx.size:
            still = speed <= 0.02
            before = float(np.sum(still[moving[0] : idx[0]]) * dt)
            after = float(np.sum(still[idx[-1] : moving[-1]]) * dt)
            rows.append((name, t[idx[0]], t[idx[-1]], p[g, 2].mean(), speed[g].mean(), rest, p[0], before, after,
                         t[moving[-1]], abs(p[-1, 0])))  # fmt: skip
        inside.append(g)
    occ = np.sum(inside, axis=0)
    rows.sort(key=lambda r: r[1])
    first, last = rows[0][1], rows[-1][2]
    span = (t >= first) & (t <= last)
    print(f"plan {plan.makespan_s:.2f} s; {len(rows)} vehicles cross the slab, first entry {first:.2f} s, last entry "
          f"{rows[-1][1]:.2f} s ({rows[-1][0]}), last exit {last:.2f} s")  # fmt: skip
    print(f"in the slab at once: max {occ.max()}, mean {occ[span].mean():.2f} between first entry and last exit; "
          f"empty {np.sum(occ[span] == 0) * dt:.2f} s of those {last - first:.2f} s")  # fmt: skip
    print(f"speed in the slab: median {np.median([r[4] for r in rows]):.2f} m/s, min {min(r[4] for r in rows):.2f}")
    print(f"rest between first and last motion: {sum(r[5] for r in rows):.1f} vehicle-s, of which before the slab "
          f"{sum(r[7] for r in rows):.1f} and after it {sum(r[8] for r in rows):.1f} (waiting for the goal)")  # fmt: skip
    for label, key, when in (("start", 6, 1), ("goal", 10, 9)):
        depth = np.round([abs(r[6][0]) if key == 6 else r[10] for r in rows], 1)
        per = "; ".join(
            f"{d:.1f} m: {np.median([r[when] for r, e in zip(rows, depth) if e == d]):.1f}" for d in np.unique(depth)
        )
        what = "slab entry" if when == 1 else "last motion"
        print(f"median {what} by {label} row (|x| of the {label}): {per}")
    heights = np.round(2.0 * np.array([r[3] for r in rows])) / 2.0  # 0.5 m bins
    for z in np.unique(heights):
        sel = [r for r, h in zip(rows, heights) if h == z]
        ent = np.array([r[1] for r in sel])
        gaps = np.diff(ent)
        print(f"  z ~ {z:.1f} m (0.5 m bins): {len(sel)} crossers, entries {ent[0]:.2f}..{ent[-1]:.2f} s, "
              f"{len(sel) / max(ent[-1] - ent[0], dt):.2f} per s, median interval {np.median(gaps) if gaps.size else 0:.2f} s")  # fmt: skip
    late = sorted(rows, key=lambda r: -r[5])[:6]
    print("longest rests (name, start, rest s, slab entry s): "
          + "; ".join(f"{r[0]} {np.round(r[6], 2).tolist()} {r[5]:.2f} {r[1]:.2f}" for r in late))  # fmt: skip
    return [r[0] for r in late]


def _goal_blockers(plan, pr, names: list[str]) -> None:
    """For ``names``: the last time another vehicle is within the swarm layer's keep-out (moving) of the
    vehicle's goal, and which, against the time the vehicle arrives there (its last motion)."""
    t, dt = plan.t_s, plan.dt_s
    idx = {n: i for i, n in enumerate(pr.names)}
    pos = {n: tr.position_m for n, tr in plan.vehicles.items()}
    out = []
    for n in names:
        a = idx[n]
        goal = pos[n][-1]
        speed = np.linalg.norm(np.gradient(pos[n], dt, axis=0), axis=1)
        arrive = float(t[np.flatnonzero(speed > 0.02)[-1]])
        last, who = -1.0, "-"
        for m, p in pos.items():
            if m == n:
                continue
            ko = pr.keepouts[(int(pr.type_index[a]), int(pr.type_index[idx[m]]))]
            hit = np.flatnonzero(ko.conflict(p - goal[None]))
            if hit.size and t[hit[-1]] > last:
                last, who = float(t[hit[-1]]), m
        out.append(f"{n} goal clear from {last + dt:.2f} s ({who}), arrives {arrive:.2f} s")
    print("goals of the longest rests: " + "; ".join(out))


def _keepouts(scenario) -> tuple[float, float, object]:
    from proxplan.planner.swarm.problem import swarm_problem

    pr = swarm_problem(scenario)
    zs = sorted({float(t.start_m[2]) for t in scenario.vehicles.values()})
    dzg = zs[-1] - zs[0]
    same = max(k.horizontal_radius_m(-1e-3, 1e-3) for k in pr.keepouts.values())
    cross = max(max(k.horizontal_radius_m(dzg, dzg), k.horizontal_radius_m(-dzg, -dzg)) for k in pr.keepouts.values())
    starts = np.array([t.start_m for t in scenario.vehicles.values()])
    pitch = float(np.min([np.min(np.abs(np.diff(np.unique(starts[:, k])))) for k in (0, 1)]))
    print(f"blocks: pitch {pitch:.2f} m; an aisle between two neighbours needs pitch >= 2 x the one-height keep-out "
          f"({2 * same:.2f} m) in the swarm layer, >= 2 x the verifier's separation ({2 * scenario.limits.min_separation_m:.2f} m) in verify")  # fmt: skip
    print(f"keep-outs: horizontal radius at one height {same:.3f} m; at the groups' height difference {dzg:.2f} m "
          f"{cross:.3f} m (largest over type pairs)")  # fmt: skip
    return same, cross, pr


def _vertical_force_check(scenario) -> None:
    from proxplan.physics import disturbance_wrench

    types = {t.vehicle.name: t.vehicle for t in scenario.vehicles.values()}
    r = np.linspace(0.0, 1.0, 21)
    dz = np.linspace(-0.5, 3.0, 71)
    rr, zz = np.meshgrid(r, dz)
    off = np.column_stack([rr.ravel() * 0.6, rr.ravel() * 0.8, -zz.ravel()])  # p_target - p_source
    top, below_none = -math.inf, 0.0
    for s in types.values():
        for g in types.values():
            fz = disturbance_wrench(s, g, off).force_N[:, 2]
            top = max(top, float(fz.max()))
            below_none = max(below_none, float(np.abs(fz[zz.ravel() <= 0.0]).max()))
    print(f"vertical force: largest F_z of any source on any target {top:.3g} N (<= 0: sources only push down); "
          f"largest |F_z| with the target not below {below_none:.3g} N")  # fmt: skip


def _one_height_packing(depth_m: float, width_m: float, sep_m: float) -> int:
    """Points on a square grid of pitch ``sep_m`` in a depth x width rectangle (a constructed arrangement:
    any bound that admits it has K >= this)."""
    return (int(math.floor(depth_m / sep_m)) + 1) * (int(math.floor(width_m / sep_m)) + 1)


def _free_y(pr, z_m: float) -> tuple[float, float]:
    ys = np.arange(-1.0, 1.0 + 1e-9, 0.005)
    pts = np.column_stack([np.zeros_like(ys), ys, np.full_like(ys, z_m)])
    free = ys[pr.static_free(pts)]
    return float(free.min()) + 0.01, float(
        free.max()
    ) - 0.01  # 1 cm in: a lane along x must stay free (probed at x = 0)


def _lane_estimate(scenario, pr, same_m: float, cross_m: float, half_depth_m: float) -> None:
    from proxplan.planner.bounds import rest_to_free_time_s, straight_time_s

    tasks = list(scenario.vehicles.values())
    lim = tasks[0].kinematic_limits
    v = lim.max_speed_mps
    groups = {-1: [t for t in tasks if t.start_m[0] < 0], 1: [t for t in tasks if t.start_m[0] > 0]}
    z = {s: float(g[0].start_m[2]) for s, g in groups.items()}
    y_lo, y_hi = (max(_free_y(pr, z[s])[0] for s in z), min(_free_y(pr, z[s])[1] for s in z))
    n_lanes = 1
    while 2 * n_lanes * same_m + cross_m - 2 * same_m <= (y_hi - y_lo) + 1e-9:  # (k-1) pitches each side + the gap
        n_lanes += 1
    n_lanes -= 1
    lanes = {-1: [y_lo + k * same_m for k in range(n_lanes)], 1: [y_hi - k * same_m for k in range(n_lanes)]}
    print(f"lanes: free centre y in the gap {y_lo:.2f}..{y_hi:.2f} m; {n_lanes} per group, pitch {same_m:.2f} m, "
          f"west->east at y {np.round(lanes[-1], 2).tolist()} z {z[-1]}, east->west at y {np.round(lanes[1], 2).tolist()} z {z[1]}")  # fmt: skip
    headway = same_m / v
    out = {}
    for how in ("optimistic", "rest-to-rest legs"):
        worst = 0.0
        for s, g in groups.items():
            order = sorted(g, key=lambda t: t.start_m[1] * -s)  # the group's lanes from their wall side
            per = math.ceil(len(order) / n_lanes)
            for k in range(n_lanes):
                lane = order[k * per : (k + 1) * per]
                y = lanes[s][k]
                mouth = np.array([-s * half_depth_m, y, z[s]])
                exit_ = np.array([s * half_depth_m, y, z[s]])
                arr = []
                for t in lane:
                    d1 = float(np.linalg.norm(mouth - t.start_m))
                    d3 = float(np.linalg.norm(t.goal_m - exit_))
                    if how == "optimistic":
                        arr.append(
                            (
                                float(rest_to_free_time_s(d1, lim)),
                                2 * half_depth_m / v + float(rest_to_free_time_s(d3, lim)),
                            )
                        )
                    else:
                        arr.append(
                            (
                                straight_time_s(d1, lim),
                                straight_time_s(2 * half_depth_m, lim) + straight_time_s(d3, lim),
                            )
                        )
                arr.sort()
                entry = -math.inf
                for a, rest in arr:
                    entry = max(a, entry + headway)
                    worst = max(worst, entry + rest)
        out[how] = worst
    print("lane-flow estimate (not a plan, not a bound; conflicts outside the slab ignored): "
          + ", ".join(f"{k} {x:.2f} s" for k, x in out.items()))  # fmt: skip


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, nargs="+", default=[64])
    ap.add_argument("--no-plan", action="store_true", help="skip planning (items 3-6 only)")
    args = ap.parse_args()

    import yaml

    from proxplan.planfile import load_scenario
    from proxplan.planner.bounds import certified_bound, slabs, throughput_time_s
    from proxplan.planner.formations import LAYOUTS

    for n in args.n:
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / f"corridor-{n}.yaml"
            path.write_text(yaml.safe_dump(LAYOUTS["corridor"](n), sort_keys=False))
            sc = load_scenario(path)
        cb = certified_bound(sc)
        wall = sc.obstacles[0]
        half_depth = 0.5 * float(wall.max_m[0] - wall.min_m[0])
        print(f"== corridor-{n}: certified bound {cb.bound_s:.2f} s ({cb.setter}); straight {cb.straight_s:.2f} s")
        if not args.no_plan:
            plan, w, c = _plan(sc)
            info = plan.metrics.get("swarm", {})
            print(f"swarm plan: {plan.makespan_s:.2f} s = {plan.makespan_s / cb.bound_s:.2f}x, {w:.1f} s wall, {c:.1f} s CPU, "
                  f"stage {info.get('stage')}: {info.get('coordination')}")  # fmt: skip
            longest = _slab_report(plan, half_depth)
        same, cross, pr = _keepouts(sc)
        if not args.no_plan:
            _goal_blockers(plan, pr, longest)
        _vertical_force_check(sc)
        sep = sc.limits.min_separation_m
        rb = max(t.body_radius_m for t in sc.vehicles.values())
        width = float(sc.obstacles[1].min_m[1] - sc.obstacles[0].max_m[1]) - 2 * rb
        k1 = _one_height_packing(2 * half_depth, width, max(sep, 2 * rb))
        slab = next(s for s in slabs(sc) if s.axis == 0 and s.box == 0)
        ceiling = throughput_time_s(sc, slab, packing=k1)
        print(f"one-height packing of the slab (separation {max(sep, 2 * rb):.2f} m, width {width:.2f} m): K_1 = {k1}; "
              f"a crossing-rate bound with K >= K_1 is at most {ceiling:.2f} s (against {cb.bound_s:.2f} s)")  # fmt: skip
        _lane_estimate(sc, pr, same, cross, half_depth)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
