"""`proxplan certify`: Monte-Carlo closed-loop flights of a plan on Dask, probabilities with Wilson
95 % intervals, a report (certify.json, histogram PNG, worst run's tracking plot)."""

from __future__ import annotations

import argparse
import json
import sys

from proxplan.cli_args import add_model_argument, load_model_argument, seed_argument


def register(subparsers) -> None:
    p = subparsers.add_parser(
        "certify",
        help="Monte-Carlo closed-loop flights of a plan under model uncertainty (Dask)",
        description=(
            "Fly DIR/plan.json N times closed loop (the simulator of 'proxplan simulate'); every run draws "
            "model parameters (a saved model's uncertainty or documented default spreads), a residual "
            "disturbance process matched to Neural-Swarm residuals, sensor noise, start-position and "
            "timing errors from its own seed (--seed, run index), so results do not depend on where runs "
            "execute. Runs go to a local Dask cluster by default, or to --scheduler tcp://HOST:PORT "
            "(docs/certify.md). Writes OUT/certify.json, OUT/runs.jsonl, OUT/authority_histogram.png and "
            "the worst run's tracking plot. Re-fly a run with 'proxplan simulate PLAN --certify-run K "
            "--seed S'."
        ),
    )
    p.add_argument("plan", help="plan.json (DESIGN.md section 4), or a directory holding one")
    p.add_argument("--runs", type=int, required=True, metavar="N", help="number of flights (>= 0)")
    p.add_argument("--seed", type=seed_argument, default=0, help="seed of all draws, 0..2^31-1 (default 0)")
    add_draw_arguments(p)
    p.add_argument(
        "--scheduler", metavar="tcp://HOST:PORT", help="address of a running 'dask scheduler' (default: local cluster)"
    )
    p.add_argument("--workers", type=int, metavar="K", help="local cluster workers (default: one per core)")
    p.add_argument("--out", required=True, metavar="DIR", help="output directory")
    p.add_argument("--json", action="store_true", help="print one JSON object on stdout")
    p.set_defaults(func=run)


def add_draw_arguments(p: argparse.ArgumentParser) -> None:
    """Flags that change the draws (shared with ``simulate --certify-run``)."""
    add_model_argument(p, "the flown world (its vehicles and effects) and its 'uncertainty' parameter spreads")
    p.add_argument("--truth", metavar="FILE.yaml", help="extra effects of the simulated world (docs/simulation.md)")
    p.add_argument(
        "--vehicles", metavar="FILE.yaml", help="fly these vehicle parameters instead of the plan's (types by name)"
    )
    p.add_argument(
        "--goal-tolerance", type=float, default=None, metavar="M",
        help="final position error that still reaches the goal, m (default 0.10)",
    )  # fmt: skip


def build_setup(args: argparse.Namespace, plan_path, notes: list[str]):
    """The CertifySetup of the parsed flags (``notes`` collects what the user should know).

    The flown world is the plan's own model (its effects included), or the ``--model`` file's
    vehicles and effects; ``--truth`` adds effects, ``--vehicles`` replaces vehicle types (as
    ``proxplan simulate``)."""
    from proxplan.certify import DEFAULT_GOAL_TOLERANCE_M, CertifySetup, Spreads
    from proxplan.fileio import UserError
    from proxplan.flightsim import load_truth_file, merge_truth, model_truth, plan_truth
    from proxplan.planfile import read_plan
    from proxplan.verify import scenario_of_plan

    plan = read_plan(plan_path)
    scenario = scenario_of_plan(plan, label=str(plan_path))
    extra = load_truth_file(args.truth) if args.truth else None
    calibrated = load_model_argument(args, "certify")
    vehicles = {}
    spreads = Spreads()
    effect_spreads: dict[str, float] = {}
    if calibrated is not None:
        truth = merge_truth(model_truth(calibrated.effects, calibrated.options.field_form), extra)
        vehicles = dict(calibrated.vehicles)
        spreads, effect_spreads = _model_spreads(calibrated.uncertainty)
        if not calibrated.uncertainty:
            notes.append(
                f"{args.model}: the model has no 'uncertainty': documented default parameter spreads (docs/certify.md)"
            )
    else:
        truth = merge_truth(plan_truth(plan), extra)
        notes.append("no --model: documented default parameter spreads (docs/certify.md)")
    if args.vehicles:
        from proxplan.physics import load_vehicle_file

        vehicles = {**vehicles, **load_vehicle_file(args.vehicles)}
    tol = DEFAULT_GOAL_TOLERANCE_M if args.goal_tolerance is None else float(args.goal_tolerance)
    if not tol > 0:
        raise UserError(f"--goal-tolerance: expected a positive distance in m, got {args.goal_tolerance}")
    return CertifySetup(
        plan=plan,
        seed=args.seed,
        authority_limit=scenario.limits.authority_fraction,
        min_separation_m=scenario.limits.min_separation_m,
        goal_tolerance_m=tol,
        truth=truth,
        vehicles=vehicles,
        effect_spreads=effect_spreads,
        spreads=spreads,
    )


def _model_spreads(uncertainty) -> tuple:
    """(Spreads of vehicle parameters, {effect.param: std}) of a model's ``uncertainty`` map."""
    from proxplan.certify import Spreads
    from proxplan.physics import EFFECT_NAMES

    if not uncertainty:
        return Spreads(), {}
    model_params: dict[str, float] = {}
    effect_params: dict[str, float] = {}
    for key, value in uncertainty.items():
        head = str(key).split(".")[0]
        (effect_params if head in EFFECT_NAMES else model_params)[str(key)] = abs(float(value))
    return Spreads(model_params, from_model=True), effect_params


def resolve_plan_path(text: str):
    from pathlib import Path

    from proxplan.fileio import UserError

    path = Path(text)
    if path.is_dir():
        path = path / "plan.json"
    if not path.exists():
        raise UserError(f"{path}: plan not found (expected DIR/plan.json from proxplan plan)")
    return path


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from proxplan.certify import certify_plan, write_report
    from proxplan.fileio import UserError, output_folder

    if args.runs < 0:
        raise UserError(f"--runs: expected a whole number >= 0, got {args.runs}")
    if args.workers is not None and args.workers < 1:
        raise UserError(f"--workers: expected a whole number >= 1, got {args.workers}")
    plan_path = resolve_plan_path(args.plan)
    notes: list[str] = []
    if args.scheduler and args.workers is not None:
        notes.append("--workers applies to the local cluster only; the --scheduler cluster has its own workers")
    setup = build_setup(args, plan_path, notes)
    out = Path(args.out)
    with output_folder(out) as stage:
        bar = None
        show = not args.json or sys.stderr.isatty()

        def progress(done: int, total: int) -> None:  # the bar starts with the first finished run
            nonlocal bar
            if bar is None and show:
                from tqdm import tqdm

                bar = tqdm(total=total, desc="certify", unit="run", leave=False)
            if bar is not None:
                bar.update(done - bar.n)

        try:
            result = certify_plan(
                setup, args.runs, scheduler=args.scheduler, n_workers=args.workers, progress=progress, notes=notes
            )
        finally:
            if bar is not None:
                bar.close()
        files = write_report(setup, result, stage)
    s = result.summary
    if args.json:
        print(json.dumps({**s, "files": {k: str(out / v) for k, v in files.items()}, "execution": result.execution}))
        return 0
    print(f"{setup.plan.scenario}: {s['runs']} runs (seed {setup.seed}) on {result.execution['workers']} worker(s)")
    for outcome in ("authority_exceeded", "separation_violated", "goal_missed", "left_tube"):
        p = s[f"p_{outcome}"]
        lo, hi = s["ci95"][outcome]
        shown = "n/a" if p is None else f"{p:.3f}"
        print(f"  P({outcome.replace('_', ' ')}) = {shown}  (95 % Wilson [{lo:.3f}, {hi:.3f}])")
    te = s["tracking_error_m"]
    if te["max"] is not None:
        print(f"  tracking error p50/p95/max = {te['p50']:.3f} / {te['p95']:.3f} / {te['max']:.3f} m")
    if result.execution["retried_runs"]:
        print(f"  {result.execution['retried_runs']} run(s) retried after a worker was lost")
    for w in s["worst_runs"][:3]:
        print(
            f"  worst run {w['index']}: usage {w['peak_authority_usage']:.3f}, tracking {w['max_tracking_error_m']:.3f} m"
        )
    for note in s["notes"]:
        print(f"note: {note}")
    print(f"report: {out / files['summary']}")
    return 0


def refly(args: argparse.Namespace, plan_path) -> dict:
    """Run ``args.certify_run`` of a certification with ``args.seed`` (``simulate --certify-run``):
    the run dict with the SimulationResult under "_result"."""
    from proxplan.certify import fly_run
    from proxplan.fileio import UserError

    if args.certify_run < 0:
        raise UserError(f"--certify-run: expected a run index >= 0, got {args.certify_run}")
    for name in ("model", "goal_tolerance"):
        if not hasattr(args, name):
            setattr(args, name, None)
    setup = build_setup(args, plan_path, [])
    return fly_run(setup, args.certify_run, keep_result=True)
