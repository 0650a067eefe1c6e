"""Write the stored reference of the verifier's equivalence test (tests/verify/test_equivalence.py).

Each case is a small plan (written as ``<case>.plan.json.gz``, self-contained: vehicle types and
scenario embedded) and what the verifier of commit 51909acc (main before issue 30 vectorised it over
vehicle pairs and stacks: every pair, every stack triple one at a time) said about it
(``<case>.expected.json.gz``): every violation of ``verify_plan`` (kind, vehicle, times, sample,
worst value, limit, detail), the wrench along the plan on its grid (force, torque, usage,
invalid zone, usage by source; :func:`proxplan.verify.wrench_along_plan`), the separation summary
and the metrics of ``finish_metrics``.

It was run once with that commit's verifier installed (re-run after issue 31 added the predicted
deflections to the tubes: 51909acc carries them; d8a46068, the first reference, did not):

    python tests/verify/reference/make_reference.py

Running it again with a later verifier would overwrite the reference with that verifier's answers:
do not, unless the verifier's numbers are meant to change (and say so in the commit).

Issue 36 changed one input of the pair checks on purpose: a disturbed vehicle's tube now grows by
its closed loop in the jet (proxplan.verify.jet_loop) instead of the static sag; its follow-up
grows every vehicle's tube by its predicted tracking error along its own reference
(proxplan.physics.tracking_loop). Only the stored
violations were re-made, on the stored plans, with that verifier (``--violations-only``); the
wrench, usage, invalid zone, separation and metrics are still 51909acc's:

    python tests/verify/reference/make_reference.py --violations-only

Issue 37 re-made them once more the same way: the tracking prediction's set-point differences now
count each jump of the reference's jerk in exactly one window (verify/tracking.py; before, a jump
on a window's edge was counted twice or not at all by rounding, so the prediction changed with a
move's start time).

Cases: straight synchronised lines of formations (pillar, circle: stacks of several sources,
separation and invalid-zone violations, authority violations), a seeded random swarm of mixed
types, the shipped three-high stack, the dock scenarios (dock pairs exempt on their approach), the
baselines' plans (no-downwash, ellipsoid: authority and invalid-zone violations), the calibrated
model's effects (examples/models/neural-swarm.yaml) and variants whose authority limit sits just
above the plain usage so that the tracking-tube authority check runs and fires.
"""

from __future__ import annotations

import copy
import gzip
import json
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[2]
sys.path.insert(0, str(REPO / "benchmarks"))

FINE_DT_S = 0.01


def _random_swarm(n: int, seed: int) -> dict:
    rng = np.random.default_rng(seed)
    types = ("crazyflie-2.1", "crazyflie-parrot", "small-quad", "large-quad")
    vehicles = {}
    for i in range(n):
        start = [round(float(x), 3) for x in (*rng.uniform(-1.2, 1.2, 2), rng.choice([0.8, 1.3, 1.8, 2.4]))]
        goal = [round(float(x), 3) for x in (*rng.uniform(-1.2, 1.2, 2), rng.choice([0.8, 1.3, 1.8, 2.4]))]
        vehicles[f"r{i:02d}"] = {"type": types[i % len(types)], "start": start, "goal": goal}
    return {
        "name": f"random-{n}",
        "workspace": {"min": [-2.5, -2.5, 0.0], "max": [2.5, 2.5, 3.5]},
        "limits": {"authority_fraction": 0.3, "min_separation_m": 0.25, "tracking_margin_m": 0.05},
        "vehicles": vehicles,
    }


def _convoy() -> dict:
    """Three columns of three mixed vehicles (stacks 0.6 m high, each level 0.12 m to the side of
    the one above) flying 2 m along x together, and one small vehicle crossing under them the
    other way: stacks of three that move, for the tracking-tube check."""
    types = ("crazyflie-parrot", "crazyflie-2.1", "small-quad")
    vehicles = {}
    for c, y in enumerate((-0.7, 0.0, 0.7)):
        for level, z in enumerate((2.0, 1.4, 0.8)):
            x0 = -1.0 + 0.12 * level
            vehicles[f"c{c}{level}"] = {
                "type": types[level],
                "start": [x0, y + 0.05 * c, z],
                "goal": [x0 + 2.0, y + 0.05 * c, z],
            }
    vehicles["under"] = {"type": "crazyflie-2.1", "start": [1.2, 0.35, 0.3], "goal": [-1.2, 0.35, 0.3]}
    return {
        "name": "convoy",
        "workspace": {"min": [-2.5, -2.0, 0.0], "max": [2.5, 2.0, 2.6]},
        "limits": {"authority_fraction": 0.5, "min_separation_m": 0.25, "tracking_margin_m": 0.06},
        "vehicles": vehicles,
    }


def _straight(doc: dict, model=None):
    from bench_verify import straight_line_plan

    return straight_line_plan(doc, model=model)[1]


def _planned(scenario_file: str, method: str):
    from proxplan.planfile import load_scenario
    from proxplan.planner import plan_scenario

    return plan_scenario(load_scenario(REPO / "scenarios" / scenario_file), method=method, seed=0)


def _with_limit(plan, fraction: float):
    out = copy.deepcopy(plan)
    out.scenario_spec["limits"]["authority_fraction"] = float(fraction)
    return out


def _tube_variant(plan):
    """The plan with its authority limit just above the largest plain usage on the fine grid, so
    the plain authority check passes and the tracking-tube check runs."""
    from proxplan.verify import scenario_of_plan, wrench_along_plan

    sc = scenario_of_plan(plan)
    t = np.arange(0.0, float(plan.t_s[-1]) + FINE_DT_S / 2, FINE_DT_S)
    plain = max(float(w.usage.max()) for w in wrench_along_plan(plan, sc, t_s=t).values())
    print(f"{plan.scenario}: largest plain authority usage {plain:.4f}")
    return _with_limit(plan, round(plain + 2e-3, 6))


def cases() -> dict:
    from proxplan.physics import load_model_file
    from proxplan.planner.formations import circle_swap, formation_change

    model = load_model_file(REPO / "examples" / "models" / "neural-swarm.yaml")
    out = {
        "pillar-8": _straight(formation_change(8)),
        "circle-8": _straight(circle_swap(8)),
        "convoy": _straight(_convoy()),
        "random-10": _straight(_random_swarm(10, seed=3)),
        "circle-6-model": _straight(circle_swap(6, types=("crazyflie-2.1", "crazyflie-parrot")), model=model),
        "three-high-stack": _planned("three_high_stack.yaml", "sampling"),
        "battery-swap": _planned("battery_swap.yaml", "sampling"),
        "dock-both-moving": _planned("dock_both_moving.yaml", "sampling"),
        "corridor-stack-no-downwash": _planned("corridor_stack.yaml", "no-downwash"),
        "corridor-stack-ellipsoid": _planned("corridor_stack.yaml", "ellipsoid"),
        "crossing-4-no-downwash": _planned("crossing_4.yaml", "no-downwash"),
    }
    out["three-high-stack-tube"] = _tube_variant(out["three-high-stack"])
    out["corridor-stack-tube"] = _tube_variant(_planned("corridor_stack.yaml", "sampling"))
    out["convoy-tube"] = _tube_variant(out["convoy"])
    return out


def expected(plan) -> dict:
    """What the installed verifier says about ``plan`` (see the module docstring)."""
    from proxplan.planner.metrics import finish_metrics
    from proxplan.verify import scenario_of_plan, separation_summary, verify_plan, wrench_along_plan

    sc = scenario_of_plan(plan)
    along = wrench_along_plan(plan, sc, t_s=plan.t_s)
    metrics_plan = copy.deepcopy(plan)
    finish_metrics(sc, metrics_plan, planning_time_s=0.0)
    return {
        "violations": [v.to_dict() for v in verify_plan(plan, sc, dt_fine_s=FINE_DT_S)],
        "wrench": {
            name: {
                "force_N": w.force_N.tolist(),
                "torque_Nm": w.torque_Nm.tolist(),
                "usage": w.usage.tolist(),
                "invalid_zone": w.invalid_zone.astype(int).tolist(),
                "usage_by_source": {s: u.tolist() for s, u in w.usage_by_source.items()},
            }
            for name, w in along.items()
        },
        "separation": separation_summary(plan, sc),
        "metrics": {k: v for k, v in metrics_plan.metrics.items() if k != "planning_time_s"},
    }


def _write(path: Path, doc) -> None:
    with gzip.open(path, "wt", encoding="utf-8") as f:
        json.dump(doc, f)


def violations_only() -> int:
    """Re-make the stored violations of every stored plan with the installed verifier (the rest of
    each expected file kept)."""
    from proxplan.planfile import plan_from_dict
    from proxplan.verify import scenario_of_plan, verify_plan

    for path in sorted(HERE.glob("*.plan.json.gz")):
        name = path.name.removesuffix(".plan.json.gz")
        with gzip.open(path, "rt", encoding="utf-8") as f:
            plan = plan_from_dict(json.load(f), label=name)
        exp_path = HERE / f"{name}.expected.json.gz"
        with gzip.open(exp_path, "rt", encoding="utf-8") as f:
            exp = json.load(f)
        exp["violations"] = [
            v.to_dict() for v in verify_plan(plan, scenario_of_plan(plan, label=name), dt_fine_s=FINE_DT_S)
        ]
        _write(exp_path, exp)
        print(f"{name}: {len(exp['violations'])} violations")
    return 0


def main() -> int:
    from collections import Counter

    from proxplan.planfile import plan_from_dict, plan_to_dict

    if {"-h", "--help"} & set(sys.argv[1:]):
        print(__doc__)
        return 0
    if "--violations-only" in sys.argv[1:]:
        return violations_only()

    for name, made in cases().items():
        doc = plan_to_dict(made)
        plan = plan_from_dict(json.loads(json.dumps(doc)), label=name)  # as the test reads it back
        exp = expected(plan)
        _write(HERE / f"{name}.plan.json.gz", doc)
        _write(HERE / f"{name}.expected.json.gz", exp)
        kinds = Counter(v["kind"] for v in exp["violations"])
        print(f"{name}: {len(plan.vehicles)} vehicles, {plan.t_s.size} samples, violations {dict(kinds)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
