"""Markdown report and PNG plots of ``proxplan evaluate`` (written into the output folder).

``report.md``, ``flights.png`` (RMSE of F_z per flight, saved model vs no model),
``regions.png`` (the same per region), ``measured_vs_predicted.png`` (F_z over time on the most
disturbed scored vehicle).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import numpy as np

from proxplan.fileio import atomic_write_text, save_figure
from proxplan.identify.data import predict
from proxplan.identify.evaluate import OVERHEAD_COUNTS, EvaluationResult
from proxplan.identify.report import band_lines, exclusion_lines, limit_lines, motor_check_lines
from proxplan.identify.strata import AUTHORITY_STATES


def _bars(ax, rows: Mapping[str, dict], title: str) -> None:
    names = list(rows)
    x = np.arange(len(names))
    model = [rows[n]["rmse_fz_N"] or 0.0 for n in names]
    none = [rows[n]["no_model_rmse_fz_N"] or 0.0 for n in names]
    ax.bar(x - 0.2, none, 0.4, color="tab:gray", label="no model")
    ax.bar(x + 0.2, model, 0.4, color="tab:green", label="saved model")
    ax.set_xticks(x, [f"{n} (n={rows[n]['n_samples']})" for n in names], rotation=40, ha="right", fontsize=8)
    ax.set_ylabel("RMSE F_z [N]")
    ax.set_title(title)
    ax.legend(fontsize=8)


def _set_overhead_bars(ax, table: dict) -> None:
    """Grouped bars: per set, RMSE F_z as a ratio to no model, one bar per number of sources overhead."""
    sets = list(table)
    labels = OVERHEAD_COUNTS
    width = 0.8 / len(labels)
    for j, c in enumerate(labels):
        vals = [table[s][c]["ratio_fz"] if table[s][c]["ratio_fz"] is not None else np.nan for s in sets]
        ax.bar(np.arange(len(sets)) + (j - 1) * width, vals, width, label=f"{c} overhead")
    ax.axhline(1.0, color="k", lw=0.6, ls=":")
    ax.set_xticks(np.arange(len(sets)), sets, rotation=30, ha="right")
    ax.set_ylabel("RMSE F_z / no model [-]")
    ax.set_title("per set and number of sources overhead (r < 3 L)")
    ax.legend(fontsize=8)


def write_plots(result: EvaluationResult, out: Path) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    doc = result.to_json()
    written = []
    for name, rows, title in (("flights.png", doc["flights"], f"{result.split} flights"),
                              ("regions.png", doc["regions"], "regions (see report)")):  # fmt: skip
        fig, ax = plt.subplots(figsize=(max(6.0, 0.6 * len(rows) + 2.0), 4))
        _bars(ax, rows, title)
        save_figure(fig, out / name, dpi=110, bbox_inches="tight")
        written.append(out / name)
    if result.set_overhead:
        fig, ax = plt.subplots(figsize=(max(6.0, 0.9 * len(result.set_overhead) + 2.0), 4))
        _set_overhead_bars(ax, doc["set_overhead"])
        save_figure(fig, out / "sets_overhead.png", dpi=110, bbox_inches="tight")
        written.append(out / "sets_overhead.png")
    if result.units and result.model is not None:
        unit = max(result.units, key=lambda u: float(np.std(u.force_N[:, 2])) if u.source_types else 0.0)
        if len(unit) > 6000:
            k = int(np.argmin(unit.force_N[:, 2]))
            unit = unit.take(np.arange(max(0, k - 3000), min(len(unit), k + 3000)))
        f, _ = predict(unit, result.model)
        fig, ax = plt.subplots(figsize=(10, 4))
        t = unit.t_s - unit.t_s[0]
        ax.plot(t, unit.force_N[:, 2], lw=0.8, color="k", label="measured (S0-11, delivered thrust)")
        ax.plot(t, f[:, 2], lw=1.0, color="tab:green", label="saved model")
        ax.set_xlabel("t [s]")
        ax.set_ylabel("F_z [N]")
        ax.set_title(f"flight {unit.flight}, vehicle {unit.name} ({unit.type})")
        ax.legend(fontsize=8)
        save_figure(fig, out / "measured_vs_predicted.png", dpi=110, bbox_inches="tight")
        written.append(out / "measured_vs_predicted.png")
    return written


def _f(x: float | None) -> str:
    return "n/a" if x is None else f"{x:.4g}"


def _ratio(a: float | None, b: float | None) -> str:
    return "n/a" if a is None or not b else f"{a / b:.2f}"


def _g(x: float | None) -> str:
    return "n/a" if x is None else f"{x:.2f}"


def authority_lines(doc: Mapping) -> list[str]:
    """The per-authority-state table (``authority`` and ``set_authority`` of the evaluate JSON):
    absolute RMSE in grams beside every ratio (a ratio alone hides a no-model error that moves)."""
    lines = ["## Per authority state", "",
             "`in_range`: every motor inside its range and the vehicle not pushed down; `at_limit`: some motor "
             "at its floor or ceiling within +-0.2 s; `knocked_down`: below 0.25 m with a source overhead. "
             "Cells: RMSE F_z in g, ratio to no model, samples (share of the squared error).", "",
             "| set | " + " | ".join(AUTHORITY_STATES) + " |", "|---|" + "---|" * len(AUTHORITY_STATES)]  # fmt: skip

    def cell(r: Mapping) -> str:
        share = r.get("share_of_sq_error")
        return (f"{_g(r['rmse_fz_g'])} g, {_ratio(r['rmse_fz_N'], r['no_model_rmse_fz_N'])} ({r['n_samples']}"
                + ("" if share is None else f", {share:.0%}") + ")")  # fmt: skip

    for k, per in doc["set_authority"].items():
        lines.append(f"| {k} | " + " | ".join(cell(per[c]) for c in AUTHORITY_STATES) + " |")
    lines.append("| **all** | " + " | ".join(cell(doc["authority"][c]) for c in AUTHORITY_STATES) + " |")
    return lines + [""]


def markdown(result: EvaluationResult, *, manifest: str, model: str, plots: list[Path]) -> str:
    doc = result.to_json()
    lines = [f"# proxplan evaluate — {model} on {manifest} ({result.split} flights)", "",
             "| | RMSE F_z [N] | RMSE F_z [g] | RMSE torque [N m] |", "|---|---|---|---|",
             f"| saved model | {_f(doc['rmse_fz_N'])} | {_g(doc['rmse_fz_g'])} | {_f(doc['rmse_torque_Nm'])} |",
             f"| no model (zero disturbance) | {_f(doc['no_model']['rmse_fz_N'])} | {_g(doc['no_model']['rmse_fz_g'])} "
             f"| {_f(doc['no_model']['rmse_torque_Nm'])} |",
             "", f"Samples scored: {doc['n_samples']} of {doc['n_rows']} log rows "
             f"({_ratio(doc['n_samples'], doc['n_rows'])}); the rest failed the quality checks (see below).", ""]  # fmt: skip
    lines += authority_lines(doc)
    lines += band_lines(doc["bands"])
    for title, rows in (("Per set", doc["sets"]), ("Per flight", doc["flights"]), ("Per vehicle", doc["per_vehicle"]),
                        ("Per region", doc["regions"])):  # fmt: skip
        lines += [f"## {title}", "", "| | RMSE F_z [g] | no model [g] | ratio | samples |", "|---|---|---|---|---|"]
        for k, r in rows.items():
            ratio = _ratio(r["rmse_fz_N"], r["no_model_rmse_fz_N"])
            lines.append(f"| {k} | {_g(r['rmse_fz_g'])} | {_g(r['no_model_rmse_fz_g'])} | {ratio} | {r['n_samples']} |")
        lines.append("")
    lines += ["## Per set and number of sources overhead", "",
              "RMSE F_z as a ratio to no model (samples); overhead = sources above within r < 3 L.", "",
              "| set | all | 0 overhead | 1 overhead | 2+ overhead |", "|---|---|---|---|---|"]  # fmt: skip
    for k, per in doc["set_overhead"].items():
        cells = [
            f"{_ratio(doc['sets'][k]['rmse_fz_N'], doc['sets'][k]['no_model_rmse_fz_N'])} ({doc['sets'][k]['n_samples']})"
        ]
        cells += [f"{_ratio(per[c]['rmse_fz_N'], per[c]['no_model_rmse_fz_N'])} ({per[c]['n_samples']})" for c in per]
        lines.append(f"| {k} | " + " | ".join(cells) + " |")
    o = doc["overhead"]
    lines.append("| **all sets** | " + " | ".join(
        [_ratio(doc["rmse_fz_N"], doc["no_model"]["rmse_fz_N"])]
        + [f"{_ratio(o[c]['rmse_fz_N'], o[c]['no_model_rmse_fz_N'])} ({o[c]['n_samples']})" for c in o]) + " |")  # fmt: skip
    lines.append("")
    lines += ["Regions: `below_source` = some source above within r < 3 L; `below_within_3L` = of those, dz < 3 L "
              "(outside the field model's zone, S0 II-A), `below_beyond_3L` = the rest; `stack` = two or more "
              "sources above; `free` = none.", ""]  # fmt: skip
    sat = doc["measurement"]["saturation"]
    lines += ["## Measurement", ""] + limit_lines(sat) + [""] + motor_check_lines(result.motor_lag_check)
    lines += [""] + [f"- note: {n}" for n in result.notes]
    lines += ["", "## Excluded samples (quality checks)", ""]
    lines += exclusion_lines(result.exclusions)
    lines += ["", "## Plots", ""] + [f"![{p.stem}]({p.name})" for p in plots]
    return "\n".join(lines) + "\n"


def write_evaluation_report(result: EvaluationResult, out_dir: str | Path, *, manifest: str, model: str) -> Path:
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    plots = write_plots(result, out)
    path = out / "report.md"
    atomic_write_text(path, markdown(result, manifest=manifest, model=model, plots=plots))
    return path
