"""Is ``proxplan verify`` sound? Every shipped scenario and seeded generated close-proximity cases
(hand-offs, stacks, crossings, docks, formation changes; mixed vehicle types) are planned, verified
and flown by ``simulate`` with the planner's model as truth (the default controller, the Crazyflie
firmware's Mellinger law; no sensor noise; ``--settle`` s of hold after the plan's end), and per case:

* **unsound**: verify passed, yet a vehicle left its tube + prediction (flown position error minus
  the tube the verifier granted, ``limits.tracking_margin_m``, minus the predicted growth of its
  tube (its tracking error along its own reference and in the jets, ``proxplan.verify.predicted_tube_growth``), > 0 somewhere, the hold included);
* **conservative**: verify rejected the plan (or the planner refused the scenario as infeasible
  for a loop not damped where a vehicle holds, re-planned here without that check and flown with a
  hold of three e-folds of the predicted growth, at most a minute), yet the flight stayed within
  tube + prediction
  (where the prediction has no bound after the end, the hold is judged against its value at the
  end) and within the authority limit;
* the worst excess (flown error - tube - prediction, m) per case; the makespan.

The cases fan out over a Dask cluster (``proxplan.fanout``; ``--workers``, ``--scheduler``); each
depends on its own seed only.

``--makespan-baseline PYTHON`` also plans every shipped scenario in fresh processes with PYTHON (an
interpreter whose ``proxplan`` is the code before the closed-loop margins, e.g. the main checkout's)
and with this checkout, and prints the makespans side by side (run from a temporary directory, so
neither imports the other's checkout).

Run: python benchmarks/bench_soundness.py [--generated 32] [--seed 0] [--method optimized]
     [--settle 6] [--workers 2] [--only NAME ...] [--makespan-baseline PYTHON] [--json OUT.json]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
SCENARIOS = REPO / "scenarios"
HOLD_LIMIT_S = 60.0
"""Longest hold flown after a plan refused for a loop not damped where it holds, s."""
TYPES = ("crazyflie-2.1", "crazyflie-parrot", "small-quad", "large-quad")
BUILTIN_L_M = {"crazyflie-2.1": 0.092, "crazyflie-parrot": 0.12, "small-quad": 0.117, "large-quad": 0.33}
"""Size L = 2 x arm length of each built-in type, m (proxplan vehicles): invalid zones are 3 L deep."""


@dataclasses.dataclass(frozen=True)
class Case:
    name: str
    kind: str
    doc: dict | None = None  # a scenario mapping (generated)
    path: str | None = None  # a scenario file (shipped)


# ---------------------------------------------------------------------------------- generated cases


def _workspace() -> dict:
    return {"min": [-3.0, -3.0, 0.0], "max": [3.0, 3.0, 3.6]}


def _handoff(rng: np.random.Generator, k: int) -> dict:
    giver = ("large-quad", "small-quad", "crazyflie-parrot", "large-quad")[k % 4]
    receiver = ("small-quad", "crazyflie-2.1", "crazyflie-parrot", "large-quad", "crazyflie-2.1")[k % 5]
    dz = 3.0 * BUILTIN_L_M[giver] + float(rng.uniform(0.05, 0.7))
    side = rng.uniform(-0.05, 0.05, 2)
    z_g = 2.3 + float(rng.uniform(0.0, 0.8))
    start = [*rng.uniform(1.0, 2.0, 1) * rng.choice([-1, 1]), *rng.uniform(-1.5, 1.5, 1), float(rng.uniform(0.5, 1.1))]
    return {
        "name": f"gen-handoff-{k}",
        "workspace": _workspace(),
        "limits": {"authority_fraction": 0.35, "min_separation_m": 0.3},
        "vehicles": {
            "giver": {"type": giver, "start": [0.0, 0.0, round(z_g, 3)], "hover": True},
            "receiver": {
                "type": receiver,
                "start": [round(float(x), 3) for x in start],
                "dock": {
                    "with": "giver",
                    "offset": [round(float(side[0]), 3), round(float(side[1]), 3), round(-dz, 3)],
                },
            },
        },
    }


def _aside_m(source: str, target: str, dz_m: float, usage: float) -> float:
    """Smallest horizontal offset, m (1 cm steps), at which ``target`` dz_m below ``source`` meets
    at most ``usage`` of its authority (the model), at least 0."""
    from proxplan.physics import BUILTIN_VEHICLES, authority_usage, disturbance_wrench

    src, tgt = BUILTIN_VEHICLES[source], BUILTIN_VEHICLES[target]
    r = np.arange(0.0, 1.5, 0.01)
    off = np.column_stack([r, np.zeros_like(r), np.full_like(r, -dz_m)])
    w = disturbance_wrench(src, tgt, off)
    ok = np.flatnonzero(authority_usage(tgt, w.force_N, w.torque_Nm) <= usage)
    return float(r[ok[0]]) if ok.size else 1.5


def _stack(rng: np.random.Generator, k: int) -> dict:
    """Two or three vehicles whose goals stand one above the other: each below the one above by
    3 L of it and more, and aside only as far as keeps it within 70 % of the authority limit."""
    n = 2 + k % 2
    limit = 0.45
    types = [TYPES[(k + i) % 4] for i in range(n)]
    x, y = rng.uniform(-0.5, 0.5, 2)
    z = 3.2
    vehicles = {}
    for i, t in enumerate(types):
        if i:
            dz = 3.0 * BUILTIN_L_M[types[i - 1]] + float(rng.uniform(0.25, 0.7))
            z -= dz
            ang = float(rng.uniform(0.0, 2.0 * np.pi))
            r = _aside_m(types[i - 1], t, dz, 0.7 * limit) + float(rng.uniform(0.0, 0.03))
            x, y = x + r * np.cos(ang), y + r * np.sin(ang)
        goal = [round(float(x), 3), round(float(y), 3), round(z, 3)]
        ang = 2.0 * np.pi * i / n + float(rng.uniform(0, 1))
        start = [
            round(2.0 * float(np.cos(ang)), 3),
            round(2.0 * float(np.sin(ang)), 3),
            round(float(rng.uniform(0.6, 1.6)), 3),
        ]
        vehicles[f"s{i}"] = {"type": t, "start": start, "goal": goal}
    return {
        "name": f"gen-stack-{k}",
        "workspace": _workspace(),
        "limits": {"authority_fraction": limit, "min_separation_m": 0.3},
        "vehicles": vehicles,
    }


def _crossing(rng: np.random.Generator, k: int) -> dict:
    n = 3 + k % 2
    vehicles = {}
    for i in range(n):
        ang = np.pi * i / n + float(rng.uniform(-0.2, 0.2))
        r = 2.0
        z = 0.9 + 0.45 * i + float(rng.uniform(-0.05, 0.05))
        a = [r * np.cos(ang), r * np.sin(ang)]
        vehicles[f"x{i}"] = {
            "type": TYPES[(k + i) % 4],
            "start": [round(float(a[0]), 3), round(float(a[1]), 3), round(z, 3)],
            "goal": [round(float(-a[0]), 3), round(float(-a[1]), 3), round(z + float(rng.uniform(-0.1, 0.1)), 3)],
        }
    if k % 3 == 0:  # and one hovering in the middle that the others pass over or under
        vehicles["h"] = {"type": TYPES[k % 4], "start": [0.0, 0.0, 2.9], "hover": True}
    return {
        "name": f"gen-crossing-{k}",
        "workspace": _workspace(),
        "limits": {"authority_fraction": 0.4, "min_separation_m": 0.3},
        "vehicles": vehicles,
    }


def _dock(rng: np.random.Generator, k: int) -> dict:
    target = ("large-quad", "small-quad", "crazyflie-parrot")[k % 3]
    docker = ("small-quad", "crazyflie-2.1", "crazyflie-2.1", "crazyflie-parrot")[k % 4]
    moving = k % 2 == 1
    if k % 3 == 2:  # a side dock
        offset = [round(float(rng.uniform(0.35, 0.5)), 3), 0.0, round(float(rng.uniform(-0.05, 0.05)), 3)]
    else:  # on top: the target holds in the docker's jet
        offset = [0.0, 0.0, round(3.0 * BUILTIN_L_M[docker] + float(rng.uniform(0.1, 0.5)), 3)]
    t_start = [round(float(x), 3) for x in (*rng.uniform(-0.5, 0.5, 2), rng.uniform(1.0, 1.6))]
    t_task = {"type": target, "start": t_start}
    if moving:
        t_task["goal"] = [round(t_start[0] + float(rng.uniform(-0.8, 0.8)), 3), round(t_start[1] + 0.6, 3), t_start[2]]
    else:
        t_task["hover"] = True
    return {
        "name": f"gen-dock-{k}",
        "workspace": _workspace(),
        "limits": {"authority_fraction": 0.4, "min_separation_m": 0.3},
        "vehicles": {
            "target": t_task,
            "docker": {
                "type": docker,
                "start": [round(float(rng.uniform(1.2, 2.0)), 3), round(float(rng.uniform(-2.0, -1.2)), 3), 2.6],
                "dock": {"with": "target", "offset": offset},
            },
        },
    }


def generated_cases(n: int, seed: int) -> list[Case]:
    """``n`` close-proximity cases, each from its own generator (``seed``, index); kinds in turn:
    hand-off, stack, crossing, dock, and a formation change of 6 or 8 mixed vehicles every 8th."""
    from proxplan.planner.formations import formation_change

    makers = (("handoff", _handoff), ("stack", _stack), ("crossing", _crossing), ("dock", _dock))
    out = []
    for i in range(n):
        rng = np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(i,)))
        if i % 8 == 7:
            doc = formation_change(6 + 2 * (i // 8 % 2), authority_fraction=0.3)
            doc["name"] = f"gen-formation-{i}"
            out.append(Case(doc["name"], "formation", doc=doc))
            continue
        kind, make = makers[i % 4]
        doc = make(rng, i // 4)
        doc["name"] = f"{doc['name']}-{i}"
        out.append(Case(doc["name"], kind, doc=doc))
    return out


def shipped_cases() -> list[Case]:
    return [Case(p.stem, "shipped", path=str(p)) for p in sorted(SCENARIOS.glob("*.yaml"))]


# ---------------------------------------------------------------------------------------- one case


def run_case(args: tuple[Case, str, float, str | None]) -> dict:
    """Plan, verify and fly one case; a JSON-able dict (module docstring); the plan is written to
    KEEP/NAME/plan.json when a folder is given."""
    case, method, settle_s, keep = args
    from proxplan.fileio import UserError
    from proxplan.flightsim import SimulationOptions, simulate_plan
    from proxplan.planfile import load_scenario, scenario_from_dict
    from proxplan.planner import InfeasibleError, PlanNotFound, plan_scenario
    from proxplan.verify import verify_plan

    out: dict = {"name": case.name, "kind": case.kind}
    t0 = time.perf_counter()
    try:
        scenario = load_scenario(case.path) if case.path else scenario_from_dict(case.doc)
    except UserError as err:
        return {**out, "status": "user-error", "message": str(err)}
    refused = None
    try:
        plan = plan_scenario(scenario, method=method, seed=0)
    except InfeasibleError as err:
        if err.details.get("kind") != "jet-loop":
            return {**out, "status": "infeasible", "message": err.message}
        refused = err.message  # fly the plan made without that verdict: was it right?
        # hold long enough for the predicted growth to show: three e-folds (at most a minute)
        settle_s = max(settle_s, min(HOLD_LIMIT_S, 3.0 / max(float(err.details["growth_ps"]), 1e-9)))
        import proxplan.planner.pipeline as pipeline

        saved = pipeline.check_goal_loops
        pipeline.check_goal_loops = lambda scenario: None
        try:
            plan = plan_scenario(scenario, method=method, seed=0)
        except (InfeasibleError, PlanNotFound) as again:
            return {**out, "status": "infeasible", "message": refused, "replanned": str(again)}
        finally:
            pipeline.check_goal_loops = saved
    except PlanNotFound as err:
        return {**out, "status": "not-found", "message": err.message}
    except UserError as err:
        return {**out, "status": "user-error", "message": str(err)}
    violations = verify_plan(plan, scenario)
    verified = not violations and refused is None
    if keep:
        from proxplan.planfile import write_plan

        write_plan(plan, Path(keep) / case.name / "plan.json")
    result = simulate_plan(plan, options=SimulationOptions(imu_noise=False, settle_s=settle_s))
    per = {}
    worst = -np.inf
    worst_held = -np.inf
    from proxplan.flightsim.report import predicted_deflection_m, record_tube_m
    from proxplan.physics import authority_usage

    usage_ok = True
    for name, rec in result.records.items():
        err = np.linalg.norm(rec.position_m - rec.ref_position_m, axis=1)
        growth = predicted_deflection_m(rec)
        finite = np.where(np.isfinite(growth), growth, growth[np.isfinite(growth)].max(initial=0.0))
        tube = record_tube_m(rec)
        excess = float(np.max(err - tube - growth))
        held = float(np.max(err - tube - finite))
        usage = float(authority_usage(rec.vehicle, rec.applied_force_N, rec.applied_torque_Nm).max(initial=0.0))
        usage_ok &= usage <= scenario.limits.authority_fraction + 1e-3
        per[name] = {"excess_m": excess, "excess_held_m": held, "max_error_m": float(err.max()),
                     "max_growth_m": float(finite.max()), "tube_m": tube, "usage": usage}  # fmt: skip
        worst, worst_held = max(worst, excess), max(worst_held, held)
    within = worst_held <= 0.0 and usage_ok and result.status.value == "complete"
    return {
        **out,
        "status": "verified" if verified else "rejected",
        "hold_s": settle_s,
        "violations": [str(v) for v in violations[:3]] + ([refused] if refused else []),
        "n_vehicles": len(plan.vehicles),
        "makespan_s": float(plan.metrics.get("makespan_s", plan.t_s[-1])),
        "flight": result.status.value,
        "worst_excess_m": float(worst),
        "worst_excess_held_m": float(worst_held),
        "unsound": bool(verified and (worst > 0.0 or result.status.value != "complete")),
        "conservative": bool(not verified and within),
        "vehicles": per,
        "wall_s": time.perf_counter() - t0,
    }


# ------------------------------------------------------------------------------------------ makespans


def _makespan(python: str, scenario: Path, tmp: Path) -> float | None:
    out = tmp / f"{scenario.stem}-{abs(hash(python)) % 10**6}"
    code = "import sys; from proxplan.cli import main; sys.exit(main())"
    run = subprocess.run(
        [python, "-c", code, "plan", str(scenario), "--out", str(out), "--json"],
        cwd=tmp, capture_output=True, text=True,
    )  # fmt: skip
    if run.returncode != 0:
        return None
    return float(json.loads(run.stdout)["metrics"]["makespan_s"])


def makespan_table(baseline_python: str) -> list[tuple[str, float | None, float | None]]:
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for path in sorted(SCENARIOS.glob("*.yaml")):
            rows.append(
                (path.stem, _makespan(baseline_python, path, Path(tmp)), _makespan(sys.executable, path, Path(tmp)))
            )
            print(f"  {path.stem}: before {rows[-1][1]}, after {rows[-1][2]}", flush=True)
    return rows


# ---------------------------------------------------------------------------------------------- main


def _cm(x: float) -> str:
    return "-" if not np.isfinite(x) else f"{100 * x:+.2f}"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--generated", type=int, default=32, help="generated cases (default 32)")
    ap.add_argument("--seed", type=int, default=0, help="seed of the generated cases (default 0)")
    ap.add_argument("--method", default="optimized", help="planner method (default optimized, the CLI's)")
    ap.add_argument("--settle", type=float, default=6.0, help="hold flown after each plan's end, s (default 6)")
    ap.add_argument("--workers", type=int, default=2, help="local Dask workers (default 2)")
    ap.add_argument("--scheduler", default=None, help="tcp://HOST:PORT of a running Dask scheduler")
    ap.add_argument("--only", nargs="*", default=None, help="run only the cases with these names")
    ap.add_argument("--no-shipped", action="store_true", help="generated cases only")
    ap.add_argument("--makespan-baseline", default=None, help="interpreter of the code before (makespan table)")
    ap.add_argument("--json", default=None, help="write every case's result to this JSON file")
    ap.add_argument("--keep", default=None, help="write each case's plan to KEEP/NAME/plan.json")
    args = ap.parse_args()

    from proxplan.fanout import fan_out

    cases = ([] if args.no_shipped else shipped_cases()) + generated_cases(args.generated, args.seed)
    if args.only:
        cases = [c for c in cases if c.name in set(args.only)]
    t0 = time.perf_counter()
    done = fan_out(
        run_case, [(c, args.method, args.settle, args.keep) for c in cases], scheduler=args.scheduler,
        n_workers=args.workers,
        progress=lambda k, n: print(f"  {k}/{n} cases flown", file=sys.stderr, flush=True),
    )  # fmt: skip
    results = done.results
    print(f"\n{'case':<28}{'kind':<10}{'n':>3}  {'verdict':<9}{'makespan':>9}  {'worst excess (cm)':>18}  note")
    for r in results:
        note = "UNSOUND" if r.get("unsound") else "conservative" if r.get("conservative") else ""
        if r["status"] in ("infeasible", "not-found", "user-error"):
            print(f"{r['name']:<28}{r['kind']:<10}{'':>3}  {r['status']:<9}{'':>9}  {'':>18}  {r['message'][:90]}")
            continue
        if r["status"] == "rejected":
            note = (note + " " + (r["violations"][0][:80] if r["violations"] else "")).strip()
        print(f"{r['name']:<28}{r['kind']:<10}{r['n_vehicles']:>3}  {r['status']:<9}{r['makespan_s']:>8.2f}s  "
              f"{_cm(r['worst_excess_m']):>8} / {_cm(r['worst_excess_held_m']):>8}  {note}")  # fmt: skip
    flown = [r for r in results if r["status"] in ("verified", "rejected")]
    verified = [r for r in flown if r["status"] == "verified"]
    rejected = [r for r in flown if r["status"] == "rejected"]
    unsound = [r for r in verified if r["unsound"]]
    conservative = [r for r in rejected if r["conservative"]]
    gen = [r for r in results if r["kind"] != "shipped"]
    print(f"\n{len(cases)} cases ({len(gen)} generated, seed {args.seed}), method {args.method}, hold {args.settle:g} s, "
          f"{time.perf_counter() - t0:.0f} s on {done.workers} workers")  # fmt: skip
    print(f"verified and flown: {len(verified)}; UNSOUND (left tube + prediction): {len(unsound)}"
          + (f" ({', '.join(r['name'] for r in unsound)})" if unsound else ""))  # fmt: skip
    if verified:
        worst = max(verified, key=lambda r: r["worst_excess_m"])
        print(f"  worst excess over verified flights: {_cm(worst['worst_excess_m'])} cm ({worst['name']})")
    print(f"rejected by verify (or refused as infeasible) and flown: {len(rejected)}; of them within tube + "
          f"prediction (conservative): {len(conservative)}"
          + (f" ({', '.join(r['name'] for r in conservative)})" if conservative else ""))  # fmt: skip
    others = [r for r in results if r["status"] not in ("verified", "rejected")]
    if others:
        print(f"no plan: {len(others)} ({', '.join(r['name'] + ': ' + r['status'] for r in others)})")
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1) + "\n")
    if args.makespan_baseline:
        print("\nmakespan of every shipped scenario, before / after the closed-loop margins (fresh processes):")
        rows = makespan_table(args.makespan_baseline)
        print("\n| scenario | before (s) | after (s) |\n|---|---|---|")
        for name, before, after in rows:
            b = "no plan" if before is None else f"{before:.2f}"
            a = "no plan" if after is None else f"{after:.2f}"
            print(f"| {name} | {b} | {a} |")
    return 1 if unsound else 0


if __name__ == "__main__":
    sys.exit(main())
