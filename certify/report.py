"""Certification report files: certify.json, a histogram PNG of peak authority usage per vehicle,
the worst run's tracking plot (re-flown locally with the same draws), runs.jsonl."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from proxplan.certify.engine import CertifyResult
from proxplan.certify.run import CertifySetup, fly_run
from proxplan.fileio import atomic_write_bytes, save_figure
from proxplan.flightsim import plot_errors


def plot_usage_histogram(setup: CertifySetup, result: CertifyResult, path: Path) -> Path:
    """Histogram of each vehicle's peak authority usage over the runs, with the scenario's limit."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(setup.plan.vehicles)
    fig, axes = plt.subplots(len(names), 1, figsize=(8, 2.4 * len(names) + 0.6), squeeze=False)
    for ax, name in zip(axes[:, 0], names):
        vals = np.array(
            [r["per_vehicle"][name]["peak_authority_usage"] for r in result.runs
             if r["per_vehicle"][name]["peak_authority_usage"] is not None]
        )  # fmt: skip
        if vals.size:
            ax.hist(vals, bins=min(40, max(5, vals.size // 5)), color="C0", alpha=0.8)
        ax.axvline(setup.authority_limit, color="C3", ls="--", label=f"limit {setup.authority_limit:g}")
        p = result.summary["per_vehicle"][name]["p_authority_exceeded"]
        ax.set_title(f"{name}: P(usage > limit) = {p if p is None else round(p, 3)}", fontsize=9)
        ax.set_ylabel("runs")
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("peak authority usage of the applied disturbance [-]")
    fig.suptitle(f"{setup.plan.scenario}: {len(result.runs)} certification runs, seed {setup.seed}")
    fig.tight_layout()
    return save_figure(fig, path, dpi=100)


def write_report(setup: CertifySetup, result: CertifyResult, stage: Path) -> dict[str, str]:
    """Write every report file into ``stage``; returns {what: file name}."""
    files = {"summary": "certify.json", "runs": "runs.jsonl", "histogram": "authority_histogram.png"}
    atomic_write_bytes(stage / files["summary"], (json.dumps(result.summary, indent=1) + "\n").encode())
    lines = "".join(json.dumps(r, sort_keys=True) + "\n" for r in result.runs)
    atomic_write_bytes(stage / files["runs"], lines.encode())
    plot_usage_histogram(setup, result, stage / files["histogram"])
    if result.runs:
        worst = result.summary["worst_runs"][0]["index"]
        flown = fly_run(setup, worst, keep_result=True)
        files["worst_run_plot"] = f"worst_run_{worst}.png"
        plot_errors(flown["_result"], stage / files["worst_run_plot"])
    return files
