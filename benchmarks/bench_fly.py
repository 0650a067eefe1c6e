"""Do plans hold when flown? Plans the shipped scenarios and formation changes of 8 and 16 vehicles
(proxplan.planner.formations), flies them closed-loop (truth = the planner's model, the default
controller: the Crazyflie firmware's Mellinger law with rate feed-forward, no sensor noise) and prints
per scenario: the largest flown and predicted authority usage and their ratio, the scenario's limit,
flown and predicted invalid-zone time, the largest tracking error without / with feed-forward against
the tube ``limits.tracking_margin_m``; then, for the battery swap and the hand-off, the most disturbed
vehicle's max altitude error without / with feed-forward of the predicted disturbance (and with
``--truth``, in a world with extra effects).

``--limits`` also prints, per built-in type, the tracking-course error at its measured limits with the
default controller, without its rate feed-forward and with RotorPy's SE(3) law (same run).
``--exports`` also exports every plan for the Crazyflie (7th-order polynomials, drag-compensated by
default), reads the export back (the vehicles' predicted flight) and flies it (the simulator then flies
the uploaded polynomials): per scenario the largest error against the plan where the plan predicts no
disturbance on the vehicle, the largest predicted deflection where it does, and the largest error
beyond that deflection, against the tube; whether the export passes verify.

Run: python benchmarks/bench_fly.py [--method sampling] [--formations 8 16] [--limits] [--exports]
     [--truth examples/truth/all_effects.yaml]
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

from proxplan.flightsim import SimulationOptions, load_truth_file, simulate_plan, simulation_metrics
from proxplan.flightsim.report import USAGE_RATIO_FLOOR, feedforward_comparison
from proxplan.planfile import load_scenario, scenario_from_dict
from proxplan.planner import plan_scenario
from proxplan.planner.formations import formation_change

REPO = Path(__file__).resolve().parents[1]
QUIET = SimulationOptions(imu_noise=False)


def fly(scenario, method: str) -> dict:
    t0 = time.perf_counter()
    plan = plan_scenario(scenario, method=method, seed=0)
    t_plan = time.perf_counter() - t0
    metrics = simulation_metrics(simulate_plan(plan, options=QUIET))
    with_ff = simulation_metrics(simulate_plan(plan, options=dataclasses.replace(QUIET, feedforward=True)))
    flown = max(m.max_authority_usage for m in metrics.values())
    predicted = max(m.predicted_max_authority_usage for m in metrics.values())
    avoided = [
        n for n, m in metrics.items() if m.predicted_time_in_invalid_zone_s == 0 and m.time_in_invalid_zone_s > 0
    ]
    return {
        "flown": flown,
        "predicted": predicted,
        "ratio": flown / predicted if predicted > USAGE_RATIO_FLOOR else float("nan"),
        "ratios": [m.usage_ratio_flown_to_predicted for m in metrics.values() if m.usage_ratio_flown_to_predicted],
        "limit": scenario.limits.authority_fraction,
        "invalid_flown": sum(m.time_in_invalid_zone_s for m in metrics.values()),
        "invalid_plan": sum(m.predicted_time_in_invalid_zone_s for m in metrics.values()),
        "entered_avoided": avoided,
        "max_err": max(m.max_position_error_m for m in metrics.values()),
        "calm_err": max(m.max_error_undisturbed_m for m in metrics.values()),
        "beyond": max(m.max_error_beyond_deflection_m for m in metrics.values()),
        "deflection": max(m.predicted_max_deflection_m for m in metrics.values()),
        "max_err_ff": max(m.max_position_error_m for m in with_ff.values()),
        "usage_ff": max(m.max_authority_usage for m in with_ff.values()),
        "tube": scenario.limits.tracking_margin_m,
        "makespan": plan.metrics["makespan_s"],
        "t_plan": t_plan,
        "plan": plan,
    }


def fly_exports(scenarios, rows) -> bool:
    """Export every plan for the Crazyflie, read the polynomials back and fly them; True when every
    export keeps its vehicles within the tube and within the scenario's limits."""
    import tempfile

    from proxplan.export import export_crazyflie
    from proxplan.planfile import read_export
    from proxplan.verify import verify_plan

    print("\nCrazyflie exports flown (read back, the uploads flown), against the plan [cm]: max error where no "
          "disturbance is predicted / predicted deflection / max error beyond it, vs tube; verify of the export")  # fmt: skip
    good = True
    for name, sc in scenarios:
        plan = rows[name]["plan"]
        with tempfile.TemporaryDirectory() as tmp:
            try:
                export_crazyflie(plan, sc, tmp, split_time=True)
            except Exception as err:  # noqa: BLE001 - report and go on
                print(f"{name:<18} export failed: {err}")
                good = False
                continue
            back = read_export(tmp)
            violations = verify_plan(back, sc)
            flown = simulate_plan(back, options=QUIET)
        metrics = simulation_metrics(flown)
        calm, beyond, defl = _against_plan(plan, flown)
        usage = max(m.max_authority_usage for m in metrics.values())
        within = max(calm, beyond) <= sc.limits.tracking_margin_m and usage <= sc.limits.authority_fraction
        good = good and within and not violations
        print(f"{name:<18}{100 * calm:6.2f} / {100 * defl:5.2f} / {100 * beyond:5.2f}  tube {100 * sc.limits.tracking_margin_m:.2f}"
              f"  usage {usage:.3f} / {sc.limits.authority_fraction:.2f}"
              f"  verify {'pass' if not violations else f'FAIL x{len(violations)}: ' + str(violations[0])}")  # fmt: skip
    return good


def _against_plan(plan, result) -> tuple[float, float, float]:
    """An export's flight measured against the *plan* (the read-back plan is the uploads' predicted
    flight): (largest error where no disturbance is predicted, largest predicted deflection, largest
    error beyond the predicted deflection), m, over every vehicle."""
    from proxplan.flightsim.report import predicted_deflection_m, undisturbed

    calm = beyond = defl_max = 0.0
    for name, rec in result.records.items():
        ref = plan.vehicles[name].sample(rec.t_s + float(plan.t_s[0]))[0]
        err = np.linalg.norm(rec.position_m - ref, axis=1)
        d = predicted_deflection_m(rec)
        quiet = undisturbed(rec, d)
        calm = max(calm, float(err[quiet].max()) if quiet.any() else 0.0)
        beyond = max(beyond, float((err - d).max()))
        defl_max = max(defl_max, float(d.max()))
    return calm, beyond, defl_max


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--method", default="sampling", help="planner method (default sampling)")
    ap.add_argument("--formations", type=int, nargs="*", default=[8, 16], help="formation sizes (default 8 16)")
    ap.add_argument("--limits", action="store_true", help="also measure the tracking course at old and new limits")
    ap.add_argument("--exports", action="store_true", help="also export, read back and fly every plan")
    ap.add_argument("--truth", default=str(REPO / "examples/truth/all_effects.yaml"), help="truth file for the FF row")
    args = ap.parse_args()

    if args.limits:
        from proxplan.flightsim.tracking import course_plan
        from proxplan.physics import BUILTIN_VEHICLES

        def course_err(veh, **kw) -> float:
            rec = simulate_plan(
                course_plan(veh, veh.kinematic_limits), options=dataclasses.replace(QUIET, settle_s=0.5, **kw)
            ).records["v"]
            return float(np.linalg.norm(rec.position_m - rec.ref_position_m, axis=1).max())

        print("course max error at the measured limits [cm]: mellinger / without rate FF / rotorpy SE(3)")
        for name, veh in BUILTIN_VEHICLES.items():
            e = course_err(veh)
            e_noff = course_err(veh, rate_feedforward=False)
            e_rp = course_err(veh, controller="rotorpy")
            print(f"{name:<17} {veh.kinematic_limits}: {100 * e:5.1f} / {100 * e_noff:5.1f} ({e_noff / e:.1f}x) / "
                  f"{100 * e_rp:5.1f} ({e_rp / e:.1f}x); tube {100 * veh.tracking_tube_m:.1f}")  # fmt: skip

    scenarios = [(p.stem, load_scenario(p)) for p in sorted((REPO / "scenarios").glob("*.yaml"))]
    for n in args.formations:
        scenarios.append((f"formation_{n}", scenario_from_dict(formation_change(n))))
    print(f"\nmethod {args.method}; truth = the planner's model; default controller; no sensor noise")
    print(f"{'scenario':<18}{'usage flown':>12}{'predicted':>10}{'ratio':>7}{'limit':>7}{'invalid flown/plan [s]':>24}"
          f"{'max err / FF [cm]':>18}{'calm / defl / beyond [cm]':>27}{'tube [cm]':>10}{'makespan':>9}{'plan [s]':>9}"
          "  entered avoided zone")  # fmt: skip
    rows = {}
    for name, sc in scenarios:
        r = fly(sc, args.method)
        rows[name] = r
        print(f"{name:<18}{r['flown']:>12.3f}{r['predicted']:>10.3f}{r['ratio']:>7.2f}{r['limit']:>7.2f}"
              f"{r['invalid_flown']:>14.2f} / {r['invalid_plan']:<7.2f}{100 * r['max_err']:>11.1f} / {100 * r['max_err_ff']:<4.1f}"
              f"{100 * r['calm_err']:>11.2f} /{100 * r['deflection']:>5.2f} /{100 * r['beyond']:>5.2f}"
              f"{100 * r['tube']:>10.2f}{r['makespan']:>9.1f}{r['t_plan']:>9.1f}  "
              f"{', '.join(r['entered_avoided']) or '-'}", flush=True)  # fmt: skip
    ok = all(
        r["flown"] <= r["limit"] and r["usage_ff"] <= r["limit"] and not r["entered_avoided"] for r in rows.values()
    )
    print(f"every vehicle within its limit and outside zones its plan avoided: {ok}")
    if args.exports:
        ok = fly_exports(scenarios, rows) and ok

    truth = load_truth_file(args.truth)
    print("\nfeed-forward: most disturbed vehicle's max altitude error without / with [cm] (factor)")
    for name in ("battery_swap", "handoff"):
        if name not in rows:
            continue
        plan = rows[name]["plan"]
        for label, tr in (("planner's model", None), (Path(args.truth).name, truth)):
            kw = {} if tr is None else {"truth": tr}
            a = simulate_plan(plan, options=QUIET, **kw)
            b = simulate_plan(plan, options=dataclasses.replace(QUIET, feedforward=True), **kw)
            cmp = feedforward_comparison(a, b)
            w = cmp["most_disturbed"]
            c = cmp["vehicles"][w]
            print(f"{name:<14}{label:<18}{w:<10}{100 * c['without']['max_altitude_error_m']:7.2f} / "
                  f"{100 * c['with']['max_altitude_error_m']:<6.2f} ({c['altitude_error_factor']:.1f}x)")  # fmt: skip
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
