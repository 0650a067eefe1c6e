"""Figures of the measurement fix and the saved-model evaluation on a manifest (issue 13 note, docs).

    python scripts/identify_figures.py manifests/neural-swarm.yaml [--out docs/figures]

Runs identify, then ``evaluate`` (no refitting) of the model as given, the calibrated model and the
final one on the test flights; prints markdown tables per flight set (the manifest's ``set``), per
number of sources overhead and per region, each RMSE of F_z also as a ratio to no model (zero disturbance, same
samples); the same with the commanded u[N] instead of the delivered thrust; and writes
``identify_thrust_measurement.png`` (commanded vs delivered motor thrust and the F_z they measure,
on the most saturated test vehicle) and ``identify_sets_overhead.png`` (ratios per set and per number
of sources overhead, before / calibrated / after).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from proxplan.identify import evaluate_model, load_manifest, run_identify, saved_model
from proxplan.identify.evaluate import EvaluationResult


def _pool(rows: list[dict]) -> tuple[float, float, int]:
    n = sum(r["n_samples"] for r in rows)
    if not n:
        return float("nan"), float("nan"), 0
    m = np.sqrt(sum(r["rmse_fz_N"] ** 2 * r["n_samples"] for r in rows) / n)
    z = np.sqrt(sum(r["no_model_rmse_fz_N"] ** 2 * r["n_samples"] for r in rows) / n)
    return float(m), float(z), n


def table(results: dict[str, EvaluationResult]) -> str:
    """Markdown: per set, per number of sources overhead, per set and overhead count (where a set has
    two or more overhead), per region; RMSE F_z with its ratio to no model, one column per model."""
    docs = {k: r.to_json() for k, r in results.items()}
    first = next(iter(docs.values()))
    pooled = [{"rmse_fz_N": d["rmse_fz_N"], "no_model_rmse_fz_N": d["no_model"]["rmse_fz_N"], "n_samples": d["n_samples"]}
              for d in docs.values()]  # fmt: skip
    rows = [(s, [[d["sets"][s]] for d in docs.values()]) for s in first["sets"]]
    rows += [("**all test flights**", [[p] for p in pooled])]
    rows += [(f"{c} sources overhead", [[d["overhead"][c]] for d in docs.values()]) for c in first["overhead"]]
    rows += [(f"{s}, {c} overhead", [[d["set_overhead"][s][c]] for d in docs.values()])
             for s in first["set_overhead"] for c in first["overhead"]
             if first["set_overhead"][s]["2+"]["n_samples"]]  # fmt: skip
    rows += [(f"region: {k}", [[d["regions"][k]] for d in docs.values()]) for k in first["regions"]]
    head = "| part | samples | no model [N] | " + " | ".join(f"{k} [N] (ratio)" for k in docs) + " |"
    out = [head, "|" + "---|" * (3 + len(docs))]
    for name, per_model in rows:
        cells = []
        m0, z0, n0 = _pool(per_model[0])
        for parts in per_model:
            m, z, _ = _pool(parts)
            cells.append(f"{m:.4f} ({m / z:.2f})" if n0 else "n/a")
        out.append(f"| {name} | {n0} | {z0:.4f} | " + " | ".join(cells) + " |")
    return "\n".join(out)


def sets_figure(results: dict[str, EvaluationResult], out: Path) -> Path:
    """``identify_sets_overhead.png``: RMSE F_z / no model per set (left) and per number of sources
    overhead (right), one bar per model (before / calibrated / after)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from proxplan.fileio import save_figure

    docs = {k: r.to_json() for k, r in results.items()}
    first = next(iter(docs.values()))
    fig, axes = plt.subplots(1, 2, figsize=(13, 4), gridspec_kw={"width_ratios": [3, 1]})
    for ax, key in zip(axes, ("sets", "overhead")):
        labels = list(first[key])
        width = 0.8 / len(docs)
        for j, (name, d) in enumerate(docs.items()):
            vals = [d[key][k]["ratio_fz"] if d[key][k]["ratio_fz"] is not None else np.nan for k in labels]
            ax.bar(np.arange(len(labels)) + (j - (len(docs) - 1) / 2) * width, vals, width, label=name)
        ax.set_xticks(np.arange(len(labels)), labels if key == "sets" else [f"{k} overhead" for k in labels],
                      rotation=30, ha="right")  # fmt: skip
        ax.axhline(1.0, color="k", lw=0.6, ls=":")
        ax.set_ylabel("test RMSE F_z / no model [-]")
    axes[0].set_title("per set (test flights)")
    axes[1].set_title("per number of sources overhead")
    axes[0].legend(fontsize=8)
    path = out / "identify_sets_overhead.png"
    save_figure(fig, path, dpi=110, bbox_inches="tight")
    return path


def thrust_figure(manifest, result, out: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from proxplan.fileio import save_figure
    from proxplan.identify import read_log
    from proxplan.identify.measure import measure_log
    from proxplan.identify.thrust_map import MotorSamples, delivered_thrust_N, saturated_samples

    best = None
    for f in manifest.flights:
        if f.split != "test":
            continue
        for v in f.vehicles:
            tmap = result.thrust_maps.get(v.type)
            log = read_log(v.log)
            if tmap is None or not log.has_pwm:
                continue
            s = MotorSamples(log.motor_thrust_N, log.motor_pwm, log.vbat_V)
            n = int(saturated_samples(tmap, s).sum())
            if best is None or n > best[0]:
                best = (n, f, v, log, s, tmap)
    assert best is not None, "no test log with PWM"
    _, f, v, log, s, tmap = best
    sat = saturated_samples(tmap, s)
    k = int(np.argmax(np.convolve(sat, np.ones(300), mode="same")))
    win = np.arange(max(0, k - 300), min(len(log), k + 300))
    from dataclasses import replace

    veh = result.base_model.vehicles[v.type]
    cmd = log.take(win)
    dlv = replace(
        cmd, motor_thrust_N=delivered_thrust_N(tmap, MotorSamples(cmd.motor_thrust_N, cmd.motor_pwm, cmd.vbat_V))
    )
    f_cmd = measure_log(veh, cmd).force_N[:, 2]
    f_dlv = measure_log(veh, dlv).force_N[:, 2]
    t = cmd.t_s - cmd.t_s[0]
    fig, axes = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    for m in range(4):
        axes[0].plot(t, cmd.motor_thrust_N[:, m], lw=0.8, color=f"C{m}", alpha=0.5, ls="--")
        axes[0].plot(t, dlv.motor_thrust_N[:, m], lw=1.0, color=f"C{m}", label=f"motor {m + 1}")
    axes[0].axhline(tmap.max_thrust_N, color="k", lw=0.6, ls=":", label="motor maximum P(x_max)")
    axes[0].set_ylabel("motor thrust [N]")
    axes[0].set_title(f"{f.name}, {v.name}: desired u[N] (dashed) vs delivered from PWM and Vbat (solid)")
    axes[0].legend(fontsize=7, ncol=5)
    axes[1].plot(t, f_cmd, color="tab:red", lw=0.9, label="F_z measured with the desired u[N]")
    axes[1].plot(t, f_dlv, color="k", lw=0.9, label="F_z measured with the delivered thrust")
    axes[1].fill_between(t, min(f_cmd.min(), f_dlv.min()), max(f_cmd.max(), f_dlv.max()), where=sat[win],
                         color="tab:orange", alpha=0.15, label="a motor saturated")  # fmt: skip
    axes[1].set_xlabel("t [s]")
    axes[1].set_ylabel("F_z [N] (S0-11)")
    axes[1].legend(fontsize=7)
    out.mkdir(parents=True, exist_ok=True)
    return save_figure(fig, out / "identify_thrust_measurement.png", dpi=110, bbox_inches="tight")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("manifest", type=Path)
    ap.add_argument("--out", type=Path, default=Path("docs/figures"))
    args = ap.parse_args()
    manifest = load_manifest(args.manifest)
    result = run_identify(manifest, thrust_summary=False)
    assert result.calibrated_model is not None
    models = {"before": result.base_model, "calibrated": result.calibrated_model, "after": result.final_model}
    delivered = {k: evaluate_model(manifest, saved_model(m, result.measure_options, result.thrust_maps))
                 for k, m in models.items()}  # fmt: skip
    print(
        f"identify after {result.after.rmse_fz_N:.6f} N, evaluate after {delivered['after'].to_json()['rmse_fz_N']:.6f} N"
    )
    doc = delivered["after"].to_json()
    print(f"rows scored: {doc['n_samples']} of {doc['n_rows']} ({doc['scored_fraction']:.3f})\n")
    print("### Delivered thrust (PWM and Vbat)\n")
    print(table(delivered))
    print("figure:", sets_figure(delivered, args.out))
    print("stack shielding:", result.stack_shielding)
    commanded = {k: evaluate_model(manifest, saved_model(m, result.measure_options, {})) for k, m in models.items()}
    print("\n### Same models, disturbance measured with the commanded u[N]\n")
    print(table(commanded))
    print("\nsaturation:", result.measurement_json()["saturation"])
    print("figure:", thrust_figure(manifest, result, args.out))


if __name__ == "__main__":
    main()
