"""What the verifier adds, on stacked levels, to what the swarm layer's keep-outs hold (issue 37,
stop 53 round 15A): per ordered pair of the scenario's types (b above a),

1. *one source*: the pair's free height (``swarm.levels.free_height_m`` on the problem's own
   keep-out, the cost map's cut-off at the authority fraction grown by tube, sampling and tracking
   bounds) and the model's usage (the verifier's, ``costmaps.sources_wrench``) of one source there,
   with the target moved towards its axis and up by the keep-out's moving growth w (as the
   verifier's tube check);
2. *sums*: the summed usage of a level of b at that gap on the densest arrangement its keep-outs
   allow (a hexagonal lattice at the least horizontal distance two vehicles can have at rest at one
   height, its n points nearest the target, n = the vehicles of type b, centred on a lattice point,
   an edge's middle and a triangle's centre, the worst kept; each source's usage with the target
   moved by w; added, usage being subadditive), and the gaps where that sum is within the fraction;
3. *the receiver's loop*: the largest deflection the verifier predicts (``verify_with_deflections``,
   tracking error and loop in the jet) for a vehicle of type a flying a straight move while a
   vehicle of type b flies the same move (same start time) at the gap above it, offset
   horizontally by 0-0.2 m ("riding under"), over moves of 0.6, 2 and 4 m, in flight and held
   after the end (the two end one above the other); and
   crossing: b hovering at the gap, a passing under it at full speed (4 m move) at 0-0.3 m.

World frame, z up; m. Run (about a minute):
    python benchmarks/bench_level_margins.py SCENARIO.yaml [--gaps 0.57 0.8 1.16 1.74]
(SCENARIO: e.g. a grid layout of ``benchmarks/bench_swarm.py --keep DIR``; the types and the free
box are taken from it).
"""

from __future__ import annotations

import argparse
import functools
import math

import numpy as np

CENTRES = ((0.0, 0.0), (0.5, 0.0), (0.5, math.sqrt(3.0) / 6.0))  # lattice units


def hex_radii(n: int, spacing_m: float) -> np.ndarray:
    """(3, n) distances (m) of the n lattice points nearest each centre, ascending."""
    k = int(math.ceil(math.sqrt(n))) + 2
    i, j = np.meshgrid(np.arange(-k, k + 1), np.arange(-k, k + 1), indexing="ij")
    pts = np.column_stack([(i + 0.5 * j).ravel(), (j * math.sqrt(3.0) / 2.0).ravel()])
    return np.stack([np.sort(np.hypot(pts[:, 0] - cx, pts[:, 1] - cy))[:n] for cx, cy in CENTRES]) * spacing_m


def usage(sc, source, target, r_m: np.ndarray, dz_m: float) -> np.ndarray:
    """The model's usage (the verifier's numbers) of one ``source`` on ``target`` at horizontal
    distances ``r_m`` and ``dz_m`` below it."""
    from proxplan.costmaps import sources_wrench
    from proxplan.physics import authority_usage

    r = np.atleast_1d(np.asarray(r_m, dtype=float))
    off = np.column_stack([r, np.zeros_like(r), -np.full_like(r, max(dz_m, 1e-3))])
    force, torque = sources_wrench(target, [(source, off)], sc.model_options, tuple(sc.effects))
    return authority_usage(target, force, torque)


def densest_level_usage(sc, source, target, radii_m: np.ndarray, tau_m: float, gap_m: float) -> float:
    """The summed usage (module, 2.) of sources at ``radii_m`` (centres, points), m, already
    shortened by the tube ``tau_m``, ``gap_m`` above the target moved up by ``tau_m``; the worst centre."""
    u = usage(sc, source, target, radii_m.ravel(), gap_m - tau_m).reshape(radii_m.shape)
    return float(u.sum(axis=1).max())


def receiver_deflection_m(
    source: str, target: str, gap_m: float, r_m: float, dist_m: float, *, riding: bool
) -> tuple[float, float]:
    """The verifier's largest predicted deflection of the target in a two-vehicle plan (module), m:
    in flight (before the last sample) and the last sample's (the hold after the plan's end, where a
    vehicle riding under another ends right under it)."""
    from proxplan.planfile import scenario_from_dict
    from proxplan.planner.swarm import SwarmOptions, swarm_timed
    from proxplan.planner.timing.plan_grid import assemble_plan
    from proxplan.verify import verify_with_deflections

    z = 0.8
    if riding:
        vehicles = {
            "t": {"type": target, "start": [-dist_m / 2, 0, z], "goal": [dist_m / 2, 0, z]},
            "s": {"type": source, "start": [-dist_m / 2, r_m, z + gap_m], "goal": [dist_m / 2, r_m, z + gap_m]},
        }
    else:
        vehicles = {
            "s": {"type": source, "start": [0, 0, z + gap_m], "hover": True},
            "t": {"type": target, "start": [-dist_m / 2, r_m, z], "goal": [dist_m / 2, r_m, z]},
        }
    doc = {
        "name": "margin",
        "workspace": {"min": [-3, -3, 0], "max": [3, 3, 3]},
        "limits": {"authority_fraction": 0.1, "min_separation_m": 0.25},
        "vehicles": vehicles,
    }
    sc = scenario_from_dict(doc, label="margin")
    timed, _ = swarm_timed(sc, SwarmOptions(seed=0, levels=False))
    plan = assemble_plan(sc, timed, method="swarm", notes=[])
    _, deflection = verify_with_deflections(plan, sc, dt_fine_s=0.01)
    d = deflection["t"]
    return float(d[:-1].max()), float(d[-1])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenario")
    ap.add_argument("--gaps", type=float, nargs="+", default=[0.57, 0.8, 1.16, 1.74])
    args = ap.parse_args()

    from proxplan.planfile import load_scenario
    from proxplan.planner.swarm.levels import free_height_m
    from proxplan.planner.swarm.problem import swarm_problem

    sc = load_scenario(args.scenario)
    pb = swarm_problem(sc)
    frac = sc.limits.authority_fraction
    span = float(pb.hi_m[2] - pb.lo_m[2])
    kos = pb.keepouts
    spacing = min(
        max(k.separation_m + k.w_rest_m, float(k.a_on_b_rest[0]), float(k.b_on_a_rest[0])) for k in kos.values()
    )
    print(
        f"{args.scenario}: authority fraction {frac}, free box height {span:.2f} m, least spacing at rest {spacing:.3f} m"
    )
    gaps_scan = np.arange(0.05, span + 1e-9, 0.01)
    for (a, b), ko in sorted(kos.items()):
        va, vb = pb.vehicles[a], pb.vehicles[b]
        tau = ko.w_move_m
        n = int((pb.type_index == b).sum())
        radii = np.maximum(hex_radii(n, spacing) - tau, 0.0)
        summed = functools.partial(densest_level_usage, sc, vb, va, radii, tau)
        free = free_height_m(ko, span)
        head = f"{vb.name} above {va.name} (w {100 * tau:.1f} cm, {n} of b):"
        if free is None:
            print(f"{head} no free height in the box")
            continue
        one = float(usage(sc, vb, va, np.array([0.0]), free - tau)[0])
        ok = [g for g in gaps_scan if g >= free and summed(g) <= frac]
        window = f"{ok[0]:.2f}-{ok[-1]:.2f} m" if ok else "none"
        print(f"{head} free height {free:.3f} m; one source there {one:.4f}; densest level there {summed(free):.4f}; "
              f"densest level within the fraction above the free height: {window}")  # fmt: skip
        for gap in args.gaps:
            if gap < free:
                continue
            rides = [
                receiver_deflection_m(vb.name, va.name, gap, r, dist, riding=True)
                for dist in (0.6, 2.0, 4.0)
                for r in (0.0, 0.05, 0.1, 0.2)
            ]
            riding, held = max(x for x, _ in rides), max(y for _, y in rides)
            crossing = max(
                receiver_deflection_m(vb.name, va.name, gap, r, 4.0, riding=False)[0] for r in (0.0, 0.1, 0.2, 0.3)
            )
            print(f"    gap {gap:.2f} m: densest level {summed(gap):.4f}; receiver's deflection riding under "
                  f"{100 * riding:.1f} cm in flight, {100 * held:.1f} cm held under it after the end; crossing under "
                  f"{100 * crossing:.1f} cm")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
