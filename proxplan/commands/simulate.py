"""`proxplan simulate`: closed-loop flight of a plan with downwash (RotorPy), metrics, PNG, logs."""

from __future__ import annotations

import argparse
import json
import sys

from proxplan.cli_args import add_model_argument, load_model_argument, seed_argument


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "simulate",
        help="fly a plan closed-loop in simulation (RotorPy + downwash model)",
        description=(
            "Fly DIR/plan.json closed-loop: every vehicle is RotorPy's multirotor model flown by the Crazyflie "
            "firmware's Mellinger law (or RotorPy's SE(3) controller) along the drag-compensated reference the "
            "export uploads (errors measured against the plan), and receives the downwash wrench of all other vehicles "
            "(costmaps model, plus the extra effects of --truth) every physics step. Writes "
            "OUT/summary.json, OUT/tracking_error.png and, with --log, Neural-Swarm logs and "
            "OUT/manifest.yaml (DESIGN.md section 6). Per vehicle the flown authority usage and "
            "invalid-zone time stand next to what the plan predicted; --feedforward compensates the "
            "predicted disturbance and reports the tracking errors without and with it. Exit 1 when a vehicle loses control (the flight "
            "diverged: status in the summary), 2 on bad input."
        ),
    )
    p.add_argument("plan", help="plan.json (DESIGN.md section 4), or a directory holding one")
    p.add_argument("--truth", metavar="FILE.yaml", help="extra effects of the simulated world (see docs/simulation.md)")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory")
    p.add_argument("--json", action="store_true", help="print one JSON summary on stdout")
    p.add_argument("--log", action="store_true", help="write Neural-Swarm logs and a manifest into OUT")
    p.add_argument("--flight-name", default=None, help="flight name in the manifest (default: scenario name)")
    p.add_argument("--split", default="train", choices=("train", "test"), help="manifest split of this flight")
    p.add_argument(
        "--vehicles",
        metavar="FILE.yaml",
        help="fly these vehicle parameters instead of the plan's (vehicles YAML; types matched by name)",
    )
    add_model_argument(
        p,
        "the simulated world: its vehicles fly (types matched by name) and all its effects act, in place of "
        "the plan's model (--truth adds to it)",
    )
    p.add_argument(
        "--seed", type=seed_argument, default=0, help="random seed of the sensor noise, 0..2^31-1 (default 0)"
    )
    p.add_argument(
        "--controller",
        choices=("mellinger", "rotorpy"),
        default="mellinger",
        help="simulated tracking controller: the Crazyflie firmware's Mellinger law with rate feed-forward "
        "from the reference jerk, 500 Hz, set-points at 100 Hz (default), or RotorPy's SE(3) law",
    )
    p.add_argument("--physics-dt", type=float, default=0.002, metavar="S", help="physics step, s (default 0.002)")
    p.add_argument("--log-dt", type=float, default=0.01, metavar="S", help="log period, s (default 0.01)")
    p.add_argument("--settle", type=float, default=1.0, metavar="S", help="hover after the plan ends, s (default 1)")
    p.add_argument("--no-noise", action="store_true", help="noise-free sensors and logs")
    p.add_argument(
        "--integral-rate", type=float, default=0.0, metavar="PER_S",
        help="add integral action on the position error, k_i / k_p in 1/s, as the seed's PID "
             "(default 0: RotorPy's PD law, which keeps a steady error under a steady disturbance)",
    )  # fmt: skip
    p.add_argument(
        "--no-drag-compensation",
        action="store_true",
        help="fly the plan itself: no rotor-drag lead in the set-points (by default the vehicles fly the "
        "compensated reference the export uploads, and errors are measured against the plan)",
    )
    p.add_argument(
        "--feedforward",
        action="store_true",
        help="add the plan's predicted disturbance force and torque to the controller's thrust and moment "
        "command (compensation); flies the plan twice, without and with, and reports both",
    )
    p.add_argument(
        "--certify-run", type=int, default=None, metavar="K",
        help="re-fly run K of 'proxplan certify' with the same draws (same --seed, --truth, --vehicles; "
             "certify's simulator settings)",
    )  # fmt: skip
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from dataclasses import replace
    from pathlib import Path

    from proxplan.fileio import UserError, atomic_write_bytes, output_folder
    from proxplan.flightsim import (
        SimulationOptions,
        feedforward_comparison,
        load_truth_file,
        merge_truth,
        model_truth,
        plan_truth,
        plot_errors,
        simulate_plan,
        summary_dict,
        write_flight_logs,
    )
    from proxplan.planfile import read_plan

    plan_path = Path(args.plan)
    if plan_path.is_dir():
        plan_path = plan_path / "plan.json"
    if not plan_path.exists():
        raise UserError(f"{plan_path}: plan not found (expected DIR/plan.json from proxplan plan)")
    for name, value in (("--physics-dt", args.physics_dt), ("--log-dt", args.log_dt)):
        if not value > 0:
            raise UserError(f"{name}: expected a positive number of seconds, got {value}")
    if not args.integral_rate >= 0:
        raise UserError(f"--integral-rate: expected a number >= 0 (1/s), got {args.integral_rate}")
    if args.settle < 0:
        raise UserError(f"--settle: expected a non-negative number of seconds, got {args.settle}")
    plan = read_plan(plan_path)
    extra = load_truth_file(args.truth) if args.truth else None
    calibrated = load_model_argument(args, "simulate")
    custom = None
    if calibrated is not None:  # the world of the calibrated model, --truth adds to it
        truth = merge_truth(model_truth(calibrated.effects, calibrated.options.field_form), extra)
        custom = dict(calibrated.vehicles)
    else:  # the world the plan was made for (its calibrated effects too), --truth adds to it
        truth = merge_truth(plan_truth(plan), extra)
    if args.vehicles:
        from proxplan.physics import load_vehicle_file

        custom = {**(custom or {}), **load_vehicle_file(args.vehicles)}
    options = SimulationOptions(
        physics_dt_s=args.physics_dt,
        log_dt_s=args.log_dt,
        settle_s=args.settle,
        imu_noise=not args.no_noise,
        seed=args.seed,
        position_integral_rate_ps=args.integral_rate,
        feedforward=args.feedforward,
        controller=args.controller,
        drag_compensation=not args.no_drag_compensation,
    )
    out = Path(args.out)
    show = not args.json or sys.stderr.isatty()
    with output_folder(out) as stage:  # every output lands together, or none
        baseline = None
        certify_run = None
        if args.certify_run is not None:
            from proxplan.commands.certify import refly

            certify_run = refly(args, plan_path)
            result = certify_run.pop("_result")
        else:
            if args.feedforward:  # the same flight without feed-forward, for the comparison
                baseline = simulate_plan(
                    plan, truth=truth, vehicles=custom, options=replace(options, feedforward=False), progress=show
                )
            result = simulate_plan(plan, truth=truth, vehicles=custom, options=options, progress=show)
        plot_errors(result, stage / "tracking_error.png")
        plot = out / "tracking_error.png"
        manifest = None
        if args.log:
            import os
            import shutil

            if (out / "manifest.yaml").exists():  # flights are added to an existing manifest
                shutil.copy2(out / "manifest.yaml", stage / "manifest.yaml")
            vfile = None
            if args.vehicles:
                vfile = os.path.relpath(Path(args.vehicles).resolve(), out.resolve())
            flight = args.flight_name or "".join(c if c.isalnum() or c in "-_" else "_" for c in plan.scenario)
            write_flight_logs(result, stage, flight_name=flight, split=args.split, vehicles_file=vfile)
            manifest = out / "manifest.yaml"
        summary = summary_dict(
            result,
            plan_path=str(plan_path),
            plot_path=str(plot),
            manifest_path=None if manifest is None else str(manifest),
        )
        summary["feedforward"] = None if baseline is None else feedforward_comparison(baseline, result)
        if certify_run is not None:
            summary["certify_run"] = certify_run
        atomic_write_bytes(stage / "summary.json", json.dumps(summary, indent=1).encode())
    completed = summary["status"] == "complete"
    if not completed:
        print(f"proxplan simulate: flight did not complete: {summary['status_detail']}", file=sys.stderr)
    if args.json:
        print(json.dumps(summary))
        return 0 if completed else 1
    print(
        f"{result.scenario}: {result.sim_time_s:.2f} s flown in {result.wall_time_s:.2f} s "
        f"({result.real_time_factor:.1f}x real time)"
    )
    print(
        f"{'vehicle':<12}{'type':<18}{'pos max/rms [cm]':>18}{'alt max/rms [cm]':>18}{'sat [s]':>9}"
        f"{'authority flown/plan':>22}{'motor':>7}{'invalid flown/plan [s]':>24}"
    )
    for name, m in summary["vehicles"].items():
        print(
            f"{name:<12}{m['type']:<18}"
            f"{100 * m['max_position_error_m']:>9.1f}/{100 * m['rms_position_error_m']:<8.1f}"
            f"{100 * m['max_altitude_error_m']:>9.1f}/{100 * m['rms_altitude_error_m']:<8.1f}"
            f"{m['motor_saturation_time_s']:>9.2f}"
            f"{m['max_authority_usage']:>14.3f}/{m['predicted_max_authority_usage']:<7.3f}{m['max_motor_usage']:>7.2f}"
            f"{m['time_in_invalid_zone_s']:>16.2f}/{m['predicted_time_in_invalid_zone_s']:<7.2f}"
        )
    if summary["feedforward"]:
        print("feed-forward of the predicted disturbance (same flight without / with):")
        print(f"{'vehicle':<12}{'pos max [cm]':>22}{'alt max [cm]':>22}{'alt factor':>12}")
        for name, c in summary["feedforward"]["vehicles"].items():
            factor = c["altitude_error_factor"]
            print(
                f"{name:<12}{100 * c['without']['max_position_error_m']:>12.2f} / "
                f"{100 * c['with']['max_position_error_m']:<7.2f}"
                f"{100 * c['without']['max_altitude_error_m']:>12.2f} / {100 * c['with']['max_altitude_error_m']:<7.2f}"
                f"{'-' if factor is None else f'{factor:.1f}x':>12}"
            )
    print(f"plot: {plot}")
    if manifest:
        print(f"logs: {manifest}")
    for note in summary["notes"]:
        print(f"note: {note}")
    if any(m["time_in_invalid_zone_s"] > 0 for m in summary["vehicles"].values()):
        print(
            "note: 'invalid' is time spent within dz <= 3 L below another vehicle, where the downwash "
            "model is extrapolated (S0 II-A)"
        )
    return 0 if completed else 1
