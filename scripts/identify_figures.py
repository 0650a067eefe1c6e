"""Figures and tables of identify / evaluate on a manifest (issue 13, 24 and 29 notes, docs).

    python scripts/identify_figures.py manifests/neural-swarm.yaml [--out docs/figures] [--json FILE]

Runs identify once, then ``evaluate`` (no refitting) of the model as given ("before"), the
calibrated model and the final one ("after") on the test flights and on the validation flights, and
prints markdown tables with the RMSE of F_z in grams beside its ratio to no model (zero disturbance,
same samples): per day (day 23 = the sets named ``day23_*``, the rest day 21 — the convention of the
shipped manifest), per set, per number of sources overhead and per authority state. Figures:

* ``identify_limits.png`` — the delivered thrust at both motor limits on the day-21 train flight
  swap_lll_01 (cf102): per-motor u[N] against what the PWM gives, and F_z measured with u[N] at the
  floor (the correction of issue 13, ceiling only) and at both limits;
* ``identify_authority.png`` — RMSE F_z [g] per authority state, day-21 test and day-23 test;
* ``identify_loss_of_authority.png`` — the loss-of-authority regime on the day-23 flights (validation
  and test): mean measured minus predicted F_z by vertical speed and by height, for the final model
  and with the fitted loss-of-authority candidates (``climb_inflow``, ``floor_stagnation``) added;
* ``identify_sets_overhead.png`` — ratios per set and per number of sources overhead.
"""

from __future__ import annotations

import argparse
import json
from dataclasses import replace
from pathlib import Path

import numpy as np

from proxplan.identify import evaluate_model, load_manifest, run_identify, saved_model
from proxplan.identify.data import predict
from proxplan.identify.evaluate import GRAMS_PER_N, EvaluationResult
from proxplan.identify.strata import AUTHORITY_STATES, authority_masks
from proxplan.physics import Effect

LOSS_OF_AUTHORITY_EFFECTS = ("climb_inflow", "floor_stagnation")


def _day(set_name: str) -> str:
    return "day 23" if set_name.startswith("day23") else "day 21"


def _pool(rows: list[dict]) -> dict:
    n = sum(r["n_samples"] for r in rows)
    if not n:
        return {"n": 0, "g": float("nan"), "g0": float("nan"), "ratio": float("nan")}
    m = np.sqrt(sum(r["rmse_fz_N"] ** 2 * r["n_samples"] for r in rows if r["n_samples"]) / n)
    z = np.sqrt(sum(r["no_model_rmse_fz_N"] ** 2 * r["n_samples"] for r in rows if r["n_samples"]) / n)
    return {"n": n, "g": m * GRAMS_PER_N, "g0": z * GRAMS_PER_N, "ratio": m / z}


def day_rows(doc: dict) -> dict[str, dict]:
    """Per day: pooled over its sets, and per authority state (pooled over its sets)."""
    out = {}
    for day in ("day 21", "day 23"):
        sets = [s for s in doc["sets"] if _day(s) == day]
        if not sets:
            continue
        out[day] = _pool([doc["sets"][s] for s in sets])
        for state in AUTHORITY_STATES:
            out[f"{day}, {state}"] = _pool([doc["set_authority"][s][state] for s in sets])
    return out


def table(docs: dict[str, dict], *, per_set: bool = True) -> str:
    """Markdown: RMSE F_z in g (ratio to no model) per day, authority state, set and overhead count."""
    first = next(iter(docs.values()))
    rows: list[tuple[str, list[dict]]] = []
    for key in day_rows(first):
        rows.append((f"**{key}**" if "," not in key else key, [day_rows(d)[key] for d in docs.values()]))
    if per_set:
        rows += [(s, [_pool([d["sets"][s]]) for d in docs.values()]) for s in first["sets"]]
        rows += [
            (f"{c} sources overhead", [_pool([d["overhead"][c]]) for d in docs.values()]) for c in first["overhead"]
        ]
    head = "| part | samples | no model [g] | " + " | ".join(f"{k} [g] (ratio)" for k in docs) + " |"
    out = [head, "|" + "---|" * (3 + len(docs))]
    for name, cells in rows:
        if not cells[0]["n"]:
            continue
        vals = " | ".join(f"{c['g']:.2f} ({c['ratio']:.2f})" for c in cells)
        out.append(f"| {name} | {cells[0]['n']} | {cells[0]['g0']:.2f} | {vals} |")
    return "\n".join(out)


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def sets_figure(docs: dict[str, dict], out: Path) -> Path:
    """``identify_sets_overhead.png``: RMSE F_z / no model per set and per number of sources overhead."""
    from proxplan.fileio import save_figure

    plt = _plt()
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
    return save_figure(fig, out / "identify_sets_overhead.png", dpi=110, bbox_inches="tight")


def authority_figure(docs: dict[str, dict], out: Path) -> Path:
    """``identify_authority.png``: RMSE F_z [g] per authority state, day-21 and day-23 test."""
    from proxplan.fileio import save_figure

    plt = _plt()
    rows = {k: day_rows(d) for k, d in docs.items()}
    days = [d for d in ("day 21", "day 23") if d in next(iter(rows.values()))]
    fig, axes = plt.subplots(1, len(days), figsize=(6 * len(days), 4), squeeze=False)
    for ax, day in zip(axes[0], days):
        labels = ["all", *AUTHORITY_STATES]
        keys = [day] + [f"{day}, {s}" for s in AUTHORITY_STATES]
        first = next(iter(rows.values()))
        width = 0.8 / (len(rows) + 1)
        ax.bar(np.arange(4) - 0.4 + width / 2, [first[k]["g0"] for k in keys], width, color="0.7", label="no model")
        for j, (name, r) in enumerate(rows.items()):
            ax.bar(np.arange(4) - 0.4 + (j + 1.5) * width, [r[k]["g"] for k in keys], width, label=name)
        ax.set_xticks(np.arange(4), [f"{lab}\n({first[k]['n']} samples)" for lab, k in zip(labels, keys)], fontsize=8)
        ax.set_ylabel("test RMSE F_z [g]")
        ax.set_title(f"{day} test flights, by authority state")
        ax.legend(fontsize=8)
    return save_figure(fig, out / "identify_authority.png", dpi=110, bbox_inches="tight")


def limits_figure(manifest, result, out: Path) -> Path:
    """``identify_limits.png`` on swap_lll_01 cf102 (day-21 train): u[N] vs what the PWM gives, and
    F_z measured with u[N] kept at the floor (issue 13: ceiling only) and at both limits."""
    from proxplan.fileio import save_figure
    from proxplan.identify.log_checks import check_log
    from proxplan.identify.measure import measure_log
    from proxplan.identify.thrust_map import FLOOR, IN_RANGE, MotorSamples, delivered_thrust_N, motor_limits
    from proxplan.identify.vehicle_log import read_log

    plt = _plt()
    entry = next(f for f in manifest.flights if f.name == "swap_lll_01")
    v = next(x for x in entry.vehicles if x.name == "cf102")
    veh = result.base_model.vehicles[v.type]
    log, _ = check_log(read_log(v.log), weight_N=veh.weight_N, ground_z_m=v.ground_z_m, options=manifest.quality,
                       motor_time_constant_s=veh.motor_time_constant_s)  # fmt: skip
    tmap = result.thrust_maps[v.type]
    s = MotorSamples(log.motor_thrust_N, log.motor_pwm, log.vbat_V)
    lim = motor_limits(tmap, s)
    both = replace(log, motor_thrust_N=delivered_thrust_N(tmap, s, lim))
    ceiling_only = replace(log, motor_thrust_N=delivered_thrust_N(tmap, s, np.where(lim == FLOOR, IN_RANGE, lim)))
    opts = replace(result.measure_options, motor_time_constant_s=veh.motor_time_constant_s)
    f_both = measure_log(veh, both, options=opts).force_N[:, 2]
    f_ceil = measure_log(veh, ceiling_only, options=opts).force_N[:, 2]
    k = int(np.argmax(f_ceil))
    win = np.arange(max(0, k - 250), min(len(log), k + 250))
    t = log.t_s[win] - log.t_s[win[0]]
    fig, axes = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    for m in range(4):
        axes[0].plot(t, log.motor_thrust_N[win, m], lw=0.8, color=f"C{m}", alpha=0.5, ls="--")
        axes[0].plot(t, both.motor_thrust_N[win, m], lw=1.0, color=f"C{m}", label=f"motor {m + 1}")
    axes[0].axhline(tmap.max_thrust_N, color="k", lw=0.6, ls=":", label="motor maximum")
    axes[0].axhline(0.0, color="k", lw=0.6)
    axes[0].set_ylim(-0.6, 1.2)
    axes[0].set_ylabel("motor thrust [N]")
    axes[0].set_title(f"{entry.name} (day-21 train), {v.name}: desired u[N] (dashed) vs delivered (solid)")
    axes[0].legend(fontsize=7, ncol=6)
    g = GRAMS_PER_N
    axes[1].plot(
        t, f_ceil[win] * g, color="tab:red", lw=0.9, label="F_z with u[N] at the floor (ceiling corrected only)"
    )
    axes[1].plot(t, f_both[win] * g, color="k", lw=0.9, label="F_z with the delivered thrust at both limits")
    lo, hi = axes[1].get_ylim()
    axes[1].fill_between(t, lo, hi, where=np.any(lim[win] == FLOOR, axis=1), color="tab:blue", alpha=0.15,
                         label="a motor at its floor (PWM 0)")  # fmt: skip
    axes[1].set_xlabel("t [s]")
    axes[1].set_ylabel("F_z [g] (S0-11)")
    axes[1].legend(fontsize=7)
    print(f"limits figure: max F_z {f_ceil.max():+.3f} N with u[N] at the floor, {f_both.max():+.3f} N at both limits")
    return save_figure(fig, out / "identify_limits.png", dpi=110, bbox_inches="tight")


def loss_of_authority_figure(result, out: Path) -> tuple[Path, dict]:
    """``identify_loss_of_authority.png``: on the day-23 flights (validation + test) the mean residual
    (measured - predicted F_z, g) of the bottom vehicles by vertical speed (all samples) and by height
    (samples at a limit or knocked down), for the final model without the loss-of-authority effects and
    with them (kept ones as kept, the others as identify fitted them on the train flights in their last
    trial). Returns the path and the RMSE per state of both models."""
    from proxplan.fileio import save_figure

    plt = _plt()
    after = result.final_model
    fitted = {e.name: e for e in after.effects if e.name in LOSS_OF_AUTHORITY_EFFECTS}  # kept ones as kept
    for t in result.trials:  # the others: their last fit (on the model they would have joined)
        if t.name in LOSS_OF_AUTHORITY_EFFECTS and t.name not in {e.name for e in after.effects}:
            fitted[t.name] = Effect(t.name, t.params)
    without = replace(after, effects=tuple(e for e in after.effects if e.name not in LOSS_OF_AUTHORITY_EFFECTS))
    models = {
        "after without them": without,
        "after + " + " + ".join(fitted): replace(without, effects=without.effects + tuple(fitted.values())),
    }
    units = [u for u in result.units if u.flight.startswith("day23") and u.scored and len(u) and u.split != "train"]
    rows: dict[str, dict] = {}
    fig, axes = plt.subplots(1, 2, figsize=(12, 4))
    vz_bins = np.linspace(-1.2, 1.2, 13)
    h_bins = np.linspace(0.05, 0.65, 13)
    for name, m in models.items():
        res, vz, h, state = [], [], [], []
        for u in units:
            res.append((u.force_N[:, 2] - predict(u, m)[0][:, 2]) * GRAMS_PER_N)
            vz.append(u.velocity_mps[:, 2])
            h.append(u.height_above_ground_m)
            st = np.full(len(u), "", dtype=object)
            for k, mask in authority_masks(u, m.vehicles).items():
                st[mask] = k
            state.append(st)
        r, vz_a, h_a, st_a = (np.concatenate(x) for x in (res, vz, h, state))
        rows[name] = {s: float(np.sqrt(np.mean(r[st_a == s] ** 2))) for s in AUTHORITY_STATES}
        rows[name]["all"] = float(np.sqrt(np.mean(r**2)))
        for ax, x, bins, sel in ((axes[0], vz_a, vz_bins, np.ones(len(r), bool)),
                                 (axes[1], h_a, h_bins, st_a != "in_range")):  # fmt: skip
            idx = np.digitize(x[sel], bins)
            centres = 0.5 * (bins[1:] + bins[:-1])
            means = [np.mean(r[sel][idx == i]) if np.sum(idx == i) > 30 else np.nan for i in range(1, len(bins))]
            ax.plot(centres, means, "o-", label=f"{name} (RMSE {rows[name]['all']:.2f} g)")
    axes[0].set_xlabel("vertical speed v_z [m/s]")
    axes[1].set_xlabel("rotor plane above the ground h [m] (motors at a limit or knocked down)")
    for ax in axes:
        ax.axhline(0.0, color="k", lw=0.6)
        ax.set_ylabel("mean measured - predicted F_z [g]")
        ax.legend(fontsize=8)
    axes[0].set_title("day-23 flights (validation + test): by vertical speed")
    axes[1].set_title("day-23 flights: by height, loss-of-authority samples")
    return save_figure(fig, out / "identify_loss_of_authority.png", dpi=110, bbox_inches="tight"), rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("manifest", type=Path)
    ap.add_argument("--out", type=Path, default=Path("docs/figures"))
    ap.add_argument("--json", type=Path, default=None, help="write the tables' numbers here")
    ap.add_argument("--save-model", type=Path, default=None, help="save identify's model here (as identify does)")
    args = ap.parse_args()
    manifest = load_manifest(args.manifest)
    result = run_identify(manifest, thrust_summary=False)
    assert result.calibrated_model is not None
    if args.save_model:
        from proxplan.commands.identify import save_model

        print("saved model:", save_model(result, args.save_model))
    models = {"before": result.base_model, "calibrated": result.calibrated_model, "after": result.final_model}
    evals: dict[str, dict[str, EvaluationResult]] = {}
    for split in ("test", "validation"):
        if not any(f.split == split for f in manifest.flights):
            continue
        evals[split] = {k: evaluate_model(manifest, saved_model(m, result.measure_options, result.thrust_maps),
                                          split=split) for k, m in models.items()}  # fmt: skip
    docs = {split: {k: r.to_json() for k, r in per.items()} for split, per in evals.items()}
    print(f"identify after {result.after.rmse_fz_N:.6f} N, evaluate after {docs['test']['after']['rmse_fz_N']:.6f} N")
    print(f"selected: {result.selected}; {result.validation}\n")
    print("### Test flights (never chose anything)\n")
    print(table(docs["test"]))
    if "validation" in docs:
        print("\n### Validation flights (chose the effects, eta and discovered terms; fitted nothing)\n")
        print(table(docs["validation"], per_set=False))
    args.out.mkdir(parents=True, exist_ok=True)
    print("\nfigure:", sets_figure(docs["test"], args.out))
    print("figure:", authority_figure(docs["test"], args.out))
    print("figure:", limits_figure(manifest, result, args.out))
    path, loa = loss_of_authority_figure(result, args.out)
    print("figure:", path)
    print("loss-of-authority candidates on day 23 (validation + test), RMSE F_z [g]:", json.dumps(loa, indent=1))
    print("stack shielding:", result.stack_shielding)
    print("motor lag check:", json.dumps(result.motor_lag_check, default=float))
    print("\nsaturation:", result.measurement_json()["saturation"])
    if args.json:
        summary = {split: {k: day_rows(d) for k, d in per.items()} for split, per in docs.items()}
        args.json.write_text(
            json.dumps(
                {
                    "days": summary,
                    "loss_of_authority": loa,
                    "selected": result.selected,
                    "trials": [t.to_json() for t in result.trials],
                },
                indent=1,
                default=float,
            )
        )


if __name__ == "__main__":
    main()
