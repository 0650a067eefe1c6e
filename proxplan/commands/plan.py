"""``proxplan plan`` and ``proxplan verify`` (argparse only at module level; heavy imports inside).

Exit codes: 0 success; 1 infeasible scenario (plan) or violations found (verify); 2 user mistake.
"""

from __future__ import annotations

import argparse
import json
import sys

from proxplan.cli_args import add_model_argument, load_model_argument, seed_argument

# the planner's METHODS (proxplan.planner.pipeline), spelled out here so that --help needs no planner import
METHOD_CHOICES = ("optimized", "sampling", "swarm", "no-downwash", "ellipsoid")


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "plan",
        help="plan a scenario: OMPL space-time sampling, optional optimisation, Ruckig timing",
        description=(
            "Plan every vehicle of SCENARIO.yaml and write DIR/plan.json, DIR/plan.png (top and side "
            "views, authority usage over time) and DIR/summary.txt. Exit 1 when the scenario is "
            "infeasible (proven: the message names the vehicle and the constraint), 3 when a search gave "
            "up without a plan ('not found within ...', which proves nothing), 2 on bad input."
        ),
    )
    p.add_argument("scenario", metavar="SCENARIO.yaml", help="scenario file (DESIGN.md section 4)")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder (created if missing)")
    p.add_argument(
        "--seed", type=seed_argument, default=0, help="random seed of the sampling planner, 0..2^31-1 (default 0)"
    )
    p.add_argument(
        "--method",
        choices=METHOD_CHOICES,
        default="optimized",
        help="optimized (default; sampling + CasADi refinement, or for swarms of 16+ vehicles the swarm layer "
        "with extra continuous re-timing), sampling, swarm (the swarm layer: joint coordination on a lattice, "
        "continuous-time planning; falls back to sampling with a note), or the baselines "
        "no-downwash (separation only) and ellipsoid (Crazyswarm keep-out ellipsoid)",
    )
    p.add_argument(
        "--time-budget",
        type=float,
        default=None,
        metavar="S",
        help="wall-clock budget of the optimiser in s (default 60); it returns the best verified "
        "improvement found by then, else the sampling plan with a note why. A swarm's optimisation "
        "(formation changes of 16 vehicles or more) runs on count budgets instead and ignores it (a note says so)",
    )
    p.add_argument(
        "--max-time",
        type=float,
        default=None,
        metavar="S",
        help="wall-clock budget of the whole plan in s (default: none); a search still running then "
        "stops and the plan is 'not found' (exit 3), never a different plan",
    )
    p.add_argument("--no-plot", action="store_true", help="skip the PNG")
    add_model_argument(
        p,
        "its vehicles override same-named types and its effects between vehicles shape the plan (replaces "
        "the scenario's model_file)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.set_defaults(func=_plan)

    v = subparsers.add_parser(
        "verify",
        help="independently re-check a plan with the disturbance model (non-zero exit on violations)",
        description=(
            "Re-sample DIR/plan.json finely and check workspace, obstacles, separation, goals/docks, "
            "speed/acceleration/jerk limits and authority usage evaluated with the model directly. "
            "Lists every violation with time and vehicle; exit 1 on any."
        ),
    )
    v.add_argument(
        "plan",
        metavar="PLAN.json",
        help="plan file, the folder holding plan.json, or a folder written by `proxplan export --format crazyflie` "
        "(the vehicles' predicted flight under its uploads is checked: where they will fly, never the raw "
        "upload as the path)",
    )
    v.add_argument(
        "--scenario", metavar="SCENARIO.yaml", help="scenario to check against (default: the one in the plan)"
    )
    v.add_argument("--dt", type=float, default=0.01, metavar="S", help="re-sampling step in s (default 0.01)")
    add_model_argument(
        v,
        "check the plan with this model's field form and effects between vehicles instead of the plan's own "
        "(the plan's vehicle parameters are kept)",
    )
    v.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    v.set_defaults(func=_verify)


def _progress_bar(enabled: bool):
    from tqdm import tqdm

    bar = tqdm(total=100, desc="plan", unit="%", file=sys.stderr, disable=not enabled, leave=False)

    def report(message: str, fraction: float | None = None) -> None:
        bar.set_description(message[:40])
        if fraction is not None:
            bar.n = int(round(100 * fraction))
        bar.refresh()

    return bar, report


def _plan(args: argparse.Namespace) -> int:
    import time
    from pathlib import Path

    from proxplan.fileio import UserError, atomic_write_text, output_folder
    from proxplan.planfile import jsonable, load_scenario, write_plan
    from proxplan.planner import InfeasibleError, PlanNotFound, plan_scenario, plan_summary
    from proxplan.verify import scenario_of_plan, verify_plan

    if args.time_budget is not None and not args.time_budget > 0:
        raise UserError(f"--time-budget: expected a positive number of seconds, got {args.time_budget:g}")
    if args.max_time is not None and not args.max_time > 0:
        raise UserError(f"--max-time: expected a positive number of seconds, got {args.max_time:g}")
    scenario = load_scenario(args.scenario, model=load_model_argument(args, "plan"))
    out = Path(args.out)
    with output_folder(out) as stage:  # nothing is written to --out unless every file is
        bar, report = _progress_bar(sys.stderr.isatty())
        try:
            plan = plan_scenario(
                scenario,
                method=args.method,
                seed=args.seed,
                progress=report,
                time_budget_s=args.time_budget,
                max_time_s=args.max_time,
            )
        except PlanNotFound as err:
            bar.close()
            print(f"proxplan plan: not found: {err.message}", file=sys.stderr)
            if args.json:
                print(json.dumps({"feasible": None, "found": False, "message": err.message, "vehicles": err.vehicles}))
            return 3
        except InfeasibleError as err:
            bar.close()
            print(
                f"proxplan plan: infeasible: vehicle '{err.vehicle}' cannot meet constraint '{err.constraint}': "
                f"{err.message}",
                file=sys.stderr,
            )
            if args.json:
                doc = {"feasible": False, "vehicle": err.vehicle, "constraint": err.constraint, "message": err.message}
                if err.details:
                    doc["diagnosis"] = err.details
                print(json.dumps(doc))
            return 1
        bar.close()
        t_verify = time.perf_counter()
        if plan.verified:  # the pipeline ran this same verifier on this same plan
            violations = []
        else:
            planned = scenario_of_plan(plan) if "assignment" in plan.metrics else scenario
            violations = verify_plan(plan, planned)
        t_verify = time.perf_counter() - t_verify
        plan.metrics["verify_violations"] = len(violations)
        write_plan(plan, stage)
        t_plot = time.perf_counter()
        if not args.no_plot:
            from proxplan.planner import plot_plan

            plot_plan(plan, scenario, stage / "plan.png")
        t_plot = time.perf_counter() - t_plot
        text = plan_summary(plan, violations=violations)
        atomic_write_text(stage / "summary.txt", text)
    plan_path, summary_path = out / "plan.json", out / "summary.txt"
    png = None if args.no_plot else out / "plan.png"
    if args.json:
        print(
            json.dumps(
                {
                    "feasible": True,
                    "plan": str(plan_path),
                    "png": str(png) if png else None,
                    "summary": str(summary_path),
                    "method": plan.method,
                    "metrics": jsonable(plan.metrics),
                    "notes": plan.notes,
                    "solver": None if plan.solver is None else plan.solver.to_dict(),
                    "verify": {"passed": not violations, "violations": [v.to_dict() for v in violations]},
                    "stage_times_s": {
                        "plan": plan.metrics.get("planning_time_s"),
                        "verify": round(t_verify, 3),
                        "plot": round(t_plot, 3),
                    },
                }
            )
        )
    else:
        sys.stdout.write(text)
        print(f"wrote {plan_path}" + (f", {png}" if png else "") + f", {summary_path}")
    return 0


def _with_model(plan, model, args: argparse.Namespace):
    """(plan, scenario) re-seen through ``model``: the vehicle types it calibrated fly the plan's
    trajectories, and its field form and effects between vehicles replace the plan's own (or
    those of --scenario)."""
    from dataclasses import replace

    from proxplan.fileio import UserError, read_yaml
    from proxplan.planfile import scenario_from_dict

    plan = replace(
        plan,
        vehicles={
            n: replace(tr, vehicle=model.vehicles.get(tr.type_name, tr.vehicle)) for n, tr in plan.vehicles.items()
        },
    )
    if args.scenario:
        doc = dict(read_yaml(args.scenario, what="scenario file") or {})
        label, source = str(args.scenario), args.scenario
    elif plan.scenario_spec is not None:
        doc, label, source = dict(plan.scenario_spec), f"{args.plan}: scenario_spec", None
    else:
        raise UserError(f"{args.plan}: scenario_spec: missing; pass the scenario with --scenario FILE.yaml")
    doc.pop("model", None)
    doc.pop("model_file", None)
    scenario = scenario_from_dict(doc, source_path=source, vehicle_types=plan.vehicle_types, label=label, model=model)
    return plan, scenario


def _verify(args: argparse.Namespace) -> int:
    from proxplan.fileio import UserError
    from proxplan.planfile import is_export_folder, load_scenario, read_export, read_plan
    from proxplan.verify import scenario_of_plan, verify_plan

    if not args.dt > 0:
        raise UserError(f"--dt: expected a positive number of seconds, got {args.dt}")
    exported = is_export_folder(args.plan)
    plan = read_export(args.plan) if exported else read_plan(args.plan)
    model = load_model_argument(args, "verify")
    if model is not None:
        plan, scenario = _with_model(plan, model, args)
    else:
        scenario = load_scenario(args.scenario) if args.scenario else scenario_of_plan(plan, label=str(args.plan))
    violations = verify_plan(plan, scenario, dt_fine_s=args.dt)
    if args.json:
        print(
            json.dumps(
                {
                    "passed": not violations,
                    "plan": str(args.plan),
                    "exported": exported,
                    "scenario": scenario.name,
                    "violations": [v.to_dict() for v in violations],
                }
            )
        )
    else:
        if violations:
            print(f"{args.plan}: {len(violations)} violation(s):")
            for v in violations:
                print(f"  {v}")
        else:
            print(
                f"{args.plan}: PASS (scenario '{scenario.name}', {len(plan.vehicles)} vehicles, checked every {args.dt:g} s"
                + (", the predicted flight of the Crazyflie polynomials)" if exported else ")")
            )
    return 1 if violations else 0
