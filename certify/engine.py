"""A certification: N runs fanned out (``fanout``: a local Dask cluster or an existing one), reduced
to probabilities with Wilson 95 % intervals, tracking-error percentiles and the worst runs.

The result dict (``CertifyResult.summary``) depends on the plan, the setup and the seed only: it
holds nothing about where runs were executed (that is ``CertifyResult.execution``), so the same seed
gives the identical JSON on one worker, two workers or a remote cluster.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any

from proxplan.certify.run import CertifySetup, fly_run
from proxplan.certify.stats import percentiles, probability
from proxplan.fanout import fan_out
from proxplan.fileio import UserError

OUTCOMES = ("authority_exceeded", "separation_violated", "goal_missed", "left_tube")
N_WORST = 5


@dataclass(frozen=True)
class CertifyResult:
    summary: dict[str, Any]  # the deterministic report (certify.json)
    runs: list[dict[str, Any]]  # per-run dicts in run order
    execution: dict[str, Any]  # scheduler, workers, retried runs


def _severity(run: dict[str, Any], limit: float) -> tuple:
    flags = sum(run[o] for o in OUTCOMES)
    return (
        run["status"] != "complete",
        flags,
        run["peak_authority_usage"] / max(limit, 1e-12),
        run["max_tracking_error_m"],
    )


def summarise_runs(setup: CertifySetup, runs: list[dict[str, Any]], notes: list[str]) -> dict[str, Any]:
    """The certification report of per-run dicts (in run order)."""
    n = len(runs)
    out: dict[str, Any] = {"runs": n, "seed": setup.seed}
    ci95 = {}
    counts = {}
    for outcome in OUTCOMES:
        prob = probability([r[outcome] for r in runs])
        out[f"p_{outcome}"] = prob["p"]
        ci95[outcome] = prob["ci95"]
        counts[outcome] = prob["count"]
    out["ci95"] = ci95
    out["counts"] = counts
    out["tracking_error_m"] = percentiles([r["max_tracking_error_m"] for r in runs])
    worst = sorted(runs, key=lambda r: _severity(r, setup.authority_limit), reverse=True)[:N_WORST]
    out["worst_runs"] = [
        {
            "index": r["index"],
            "seed": r["seed"],
            "status": r["status"],
            **{o: r[o] for o in OUTCOMES},
            "peak_authority_usage": r["peak_authority_usage"],
            "max_tracking_error_m": r["max_tracking_error_m"],
            "refly": f"proxplan simulate PLAN --certify-run {r['index']} --seed {setup.seed} --out DIR",
        }
        for r in worst
    ]
    per_vehicle = {}
    for name in setup.plan.vehicles:
        vals = [r["per_vehicle"][name] for r in runs]
        exceeded = [
            r["status"] != "complete" or (v["peak_authority_usage"] or 0.0) > setup.authority_limit
            for r, v in zip(runs, vals)
        ]
        prob = probability(exceeded)
        left = probability(
            [
                r["status"] != "complete" or v["tube_excess_m"] is None or v["tube_excess_m"] > 0.0
                for r, v in zip(runs, vals)
            ]
        )
        excess = [v["tube_excess_m"] for v in vals if v["tube_excess_m"] is not None]
        seps = [v["min_separation_m"] for v in vals if v["min_separation_m"] is not None]
        per_vehicle[name] = {
            "type": setup.plan.vehicles[name].type_name,
            "p_authority_exceeded": prob["p"],
            "ci95": prob["ci95"],
            "peak_authority_usage": percentiles([v["peak_authority_usage"] for v in vals]),
            "tracking_error_m": percentiles([v["max_tracking_error_m"] for v in vals]),
            "final_error_m": percentiles([v["final_error_m"] for v in vals]),
            "min_separation_m": min(seps) if seps else None,
            "p_left_tube": left["p"],
            "ci95_left_tube": left["ci95"],
            "tube_excess_m": percentiles(excess) if excess else None,
        }
    out["per_vehicle"] = per_vehicle
    out["limits"] = {
        "authority_fraction": setup.authority_limit,
        "min_separation_m": setup.min_separation_m,
        "goal_tolerance_m": setup.goal_tolerance_m,
    }
    out["draws"] = {
        "spreads": "model file" if setup.spreads.from_model else "documented defaults (docs/certify.md)",
        "spreads_absolute": dict(setup.spreads.absolute),
        "effect_spreads": dict(setup.effect_spreads),
        "noise": asdict(setup.noise),
        "truth": setup.truth.to_dict(),
    }
    out["notes"] = list(notes)
    return out


def certify_plan(
    setup: CertifySetup,
    runs: int,
    *,
    scheduler: str | None = None,
    n_workers: int | None = None,
    progress: Callable[[int, int], None] | None = None,
    notes: list[str] | None = None,
) -> CertifyResult:
    """Fly runs 0..runs-1 of ``setup`` on Dask and summarise them."""
    if runs < 0:
        raise UserError(f"--runs: expected a whole number >= 0, got {runs}")
    notes = list(notes or [])
    if setup.tube_growth is None:  # once here, not in every run
        from dataclasses import replace

        from proxplan.verify import predicted_tube_growth

        setup = replace(setup, tube_growth=predicted_tube_growth(setup.plan))
    if runs == 0:
        notes.append("--runs 0: no flights; probabilities are undefined (null) and their intervals [0, 1]")
    task = functools.partial(fly_run, setup)
    result = fan_out(task, list(range(runs)), scheduler=scheduler, n_workers=n_workers, progress=progress)
    execution = {"scheduler": result.scheduler or ("local" if scheduler is None else scheduler),
                 "workers": result.workers, "retried_runs": result.retried}  # fmt: skip
    return CertifyResult(summarise_runs(setup, result.results, notes), result.results, execution)
