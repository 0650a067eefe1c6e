"""How well the predicted tracking error along a vehicle's own reference
(``proxplan.physics.tracking_response`` through ``proxplan.verify.tracking.tracking_along_plan``)
matches what ``simulate`` flies, with no jet: every built-in type on its ``track-limits`` course at
its measured limits, and any plan files given (e.g. ``bench_soundness.py --keep DIR``'s), each
vehicle flown with the default controller, no sensor noise.

Per vehicle: the flown error's largest value and 99 % quantile, the predicted error's largest value,
the residual |flown - predicted| (vector difference, over the plan) largest and 99 % quantile, the
tube the verifier granted, and the worst of (flown - tube - predicted growth, the verifier's, the
jets included) and of (flown - tube) alone; cm.

Run: python benchmarks/bench_tracking.py [--no-courses] [PLAN.json ...]
"""

from __future__ import annotations

import argparse
import sys

import numpy as np


def _row(label: str, rec, trajectory, t_end_s: float) -> str:
    from proxplan.flightsim.report import predicted_deflection_m, record_tube_m
    from proxplan.verify.tracking import tracking_along_plan

    t = np.arange(0.0, t_end_s + 0.005, 0.01)
    pred = tracking_along_plan(trajectory, t)
    err = rec.position_m - rec.ref_position_m
    flown = np.linalg.norm(err, axis=1)
    inside = rec.t_s <= t[-1]
    pv = np.stack([np.interp(rec.t_s, pred.t_s, pred.error_m[:, i]) for i in range(3)], axis=1)
    resid = np.linalg.norm(err - pv, axis=1)[inside]
    tube = record_tube_m(rec)
    growth = predicted_deflection_m(rec)
    return (
        f"{label:<34}{100 * flown.max():6.2f} {100 * np.quantile(flown, 0.99):6.2f}  {100 * np.linalg.norm(pred.error_m, axis=1).max():6.2f}"
        f"  {100 * resid.max():6.2f} {100 * np.quantile(resid, 0.99):6.2f}  {100 * tube:5.2f}"
        f"  {100 * np.max(flown - tube - growth):+6.2f}  {100 * np.max(flown - tube):+6.2f}"
    )  # fmt: skip


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("plans", nargs="*", help="plan.json files to fly as well")
    ap.add_argument("--no-courses", action="store_true", help="skip the built-in types' courses")
    args = ap.parse_args()

    from proxplan.flightsim import SimulationOptions, simulate_plan
    from proxplan.flightsim.tracking import course_plan
    from proxplan.physics import BUILTIN_VEHICLES
    from proxplan.planfile import read_plan

    print(f"{'vehicle':<34}{'flown max / q99':>13}  {'pred':>6}  {'resid max / q99':>13}  {'tube':>5}  "
          f"{'beyond tube+growth':>6}  {'beyond tube':>6}  (cm)")  # fmt: skip
    options = SimulationOptions(imu_noise=False, settle_s=0.0)
    if not args.no_courses:
        for name, vehicle in BUILTIN_VEHICLES.items():
            plan = course_plan(vehicle, vehicle.kinematics)
            rec = simulate_plan(plan, options=options).records["v"]
            print(_row(f"{name} (course)", rec, plan.vehicles["v"], float(plan.t_s[-1])), flush=True)
    for path in args.plans:
        plan = read_plan(path)
        result = simulate_plan(plan, options=options)
        for name, rec in result.records.items():
            label = f"{path.split('/')[-2] if '/' in path else path}:{name} ({rec.vehicle.name})"
            print(_row(label[:33], rec, plan.vehicles[name], float(plan.t_s[-1])), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
