"""Where is the real residual? Stacks, a source's jet meeting the ground, the near field (issue 13).

Runs ``identify`` on the shipped Neural-Swarm manifest, takes the model it ends with (calibrated +
kept effects, without discovered terms), and on every sample of a vehicle UNDER another one
(dz > 0, r < L of the source) compares measured and predicted F_z (world z, N), on train and test
flights. Samples in motor-saturated stretches (:func:`saturated`: the commanded u[N] runs away from
what the logged PWM delivers) are left out.

Three candidates:
(a) stacks — samples with TWO sources above (dz > 0, r < L each);
(b) the jet meeting the ground — the target's height above ground h in units of the source's depth
    dz above it (h < 2 dz: the jet reaches the floor within one more depth);
(c) the near field — measured / predicted F_z binned in dz / L (L the source's size), dz < 3 L vs beyond.

Writes a PNG and a JSON of the numbers into ``--out`` (default docs/figures).

    python scripts/residual_physics.py [--out docs/figures]
"""

from __future__ import annotations

import argparse
import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

from proxplan.identify import IdentifyOptions, load_manifest, run_identify
from proxplan.identify.data import predict

MANIFEST = Path(__file__).resolve().parents[1] / "manifests" / "neural-swarm.yaml"


def saturated(path: Path, t_s: np.ndarray) -> np.ndarray:
    """Per sample at ``t_s``: some motor's commanded force u[N] is more than 15 % (+ 0.01 N) above
    what its PWM delivers, within +-0.1 s. The PWM -> force map is a quadratic fitted on this log's
    samples with PWM < 0.8 (motors far from saturation), all four motors pooled."""
    d = pd.read_csv(path)
    t = d.iloc[:, 0].to_numpy() * 1e-6
    pwm = d[[f"u{i}[PWM]" for i in range(1, 5)]].to_numpy()
    u = d[[f"u{i}[N]" for i in range(1, 5)]].to_numpy()
    low = pwm < 0.8
    coef = np.polyfit(pwm[low], u[low], 2)
    hot = (u > 1.15 * np.polyval(coef, pwm) + 0.01).any(axis=1).astype(float)
    hot = np.convolve(hot, np.ones(21), mode="same") > 0  # +-0.1 s at 100 Hz
    idx = np.clip(np.searchsorted(t, t_s), 0, len(t) - 1)
    return hot[idx]


def _under_mask(u, model) -> np.ndarray:
    m = np.zeros(len(u), dtype=bool)
    for stype, off in zip(u.source_types, u.source_offsets_m):
        m |= (-off[:, 2] > 0) & (np.hypot(off[:, 0], off[:, 1]) < model.vehicles[stype].size_m)
    return m


def fit_candidates(result, logs: dict) -> dict:
    """Recalibrate on the UNSATURATED train samples, then fit thrust_bias and, on top of it, each
    candidate (near_field, ground_jet) on them; F_z RMSE on unsaturated TEST samples, all and under a source."""
    from proxplan.identify import IdentifyOptions as Opt
    from proxplan.identify.data import errors
    from proxplan.identify.effect_selection import fit_effect
    from proxplan.identify.pipeline import calibrate_model

    opts = Opt(discover=False)
    keep = []
    for u in result.units:
        if len(u):
            idx = np.flatnonzero(~saturated(logs[(u.flight, u.name)], u.t_s))
            keep.append(u.take(idx))
    train = [u for u in keep if u.split == "train" and len(u)]
    test = [u for u in keep if u.split == "test" and len(u)]
    under = [u.take(np.flatnonzero(_under_mask(u, result.base_model))) for u in test if u.source_types]
    under = [u for u in under if len(u)]
    calibrated, _ = calibrate_model(train, result.base_model, options=opts)
    _, with_bias, _, _ = fit_effect("thrust_bias", train, calibrated, options=opts)
    models = {"no_model": None, "as_given": result.base_model, "calibrated": calibrated, "+thrust_bias": with_bias}
    for name in ("near_field", "ground_jet"):
        eff, m, _, _ = fit_effect(name, train, with_bias, options=opts)
        models[f"+thrust_bias+{name}"] = m
        models[f"+thrust_bias+{name}"] = replace(m, effects=m.effects)
        models[f"{name}_params"] = eff.full_params()  # type: ignore[assignment]
    from proxplan.identify import discover_terms, validation_split

    discovered_model, discovered = discover_terms(
        *validation_split(train)[:2], models["+thrust_bias+ground_jet"], test=test
    )
    models["+thrust_bias+ground_jet+discovered"] = discovered_model
    out: dict = {"n_train": sum(len(u) for u in train), "n_test": sum(len(u) for u in test),
                 "n_test_under_a_source": sum(len(u) for u in under)}  # fmt: skip
    for key, m in models.items():
        if key.endswith("_params"):
            out[key] = m
        elif m is None:
            out[key] = {
                "rmse_fz_N": float(np.sqrt(np.mean(np.concatenate([u.force_N[:, 2] for u in test]) ** 2))),
                "rmse_fz_N_under": float(np.sqrt(np.mean(np.concatenate([u.force_N[:, 2] for u in under]) ** 2))),
            }
        else:
            out[key] = {"rmse_fz_N": errors(test, m).rmse_fz_N, "rmse_fz_N_under": errors(under, m).rmse_fz_N}
    out["discovered"] = discovered
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("docs/figures"))
    args = ap.parse_args()
    manifest = load_manifest(MANIFEST)
    result = run_identify(manifest, options=IdentifyOptions(discover=False), thrust_summary=False)
    model = result.final_model
    logs = {(f.name, v.name): manifest.root / v.log for f in manifest.flights for v in f.vehicles}
    rows = []
    for u in result.units:
        if not u.source_types or not len(u):
            continue
        pred = predict(u, model)[0][:, 2]
        base_only = predict(u, replace(model, effects=tuple(e for e in model.effects if e.name == "thrust_bias")))[0]
        sat = saturated(logs[(u.flight, u.name)], u.t_s)
        for stype, off in zip(u.source_types, u.source_offsets_m):
            size = model.vehicles[stype].size_m
            dz, r = -off[:, 2], np.hypot(off[:, 0], off[:, 1])
            under = (dz > 0) & (r < size)
            n_above = sum(((-o[:, 2] > 0) & (np.hypot(o[:, 0], o[:, 1]) < size)) for o in u.source_offsets_m)
            rows.append(pd.DataFrame({
                "set": u.flight.rsplit("_", 1)[0], "split": u.split, "target": u.type, "source": stype,
                "dz_L": dz / size, "h_over_dz": u.height_above_ground_m / np.maximum(dz, 1e-3),
                "h_m": u.height_above_ground_m, "measured_N": u.force_N[:, 2], "predicted_N": pred,
                "base_N": base_only[:, 2], "saturated": sat, "under": under, "n_above": n_above,
            })[under])  # fmt: skip
    df = pd.concat(rows, ignore_index=True)
    ok = df[~df.saturated]
    out: dict = {
        "samples_under_a_source": int(len(df)),
        "saturated_fraction_under_a_source": float(df.saturated.mean()),
        "a_stacks": {"samples_with_two_sources_above": int((df.n_above >= 2).sum())},
        "b_ground": {
            "samples_h_below_2dz": int((ok.h_over_dz < 2).sum()),
            "h_m_min_under_a_source": float(ok.h_m.min()),
            "h_over_dz_quantiles_5_50_95": [float(q) for q in ok.h_over_dz.quantile([0.05, 0.5, 0.95])],
        },
        "c_near_field": {},
    }
    H_EDGES = np.array([0.0, 0.75, 1.0, 1.25, 1.5, 2.0, 3.0, 6.0])
    edges = np.array([0.0, 1.0, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 8.0])
    fig_rows = []
    for (tgt, src), g in ok.groupby(["target", "source"]):
        key = f"{src} above {tgt}"
        per = []
        for lo, hi in zip(edges[:-1], edges[1:]):
            b = g[(g.dz_L >= lo) & (g.dz_L < hi)]
            if len(b) < 30:
                continue
            per.append({"dz_L": [float(lo), float(hi)], "n": int(len(b)),
                        "measured_N": float(b.measured_N.mean()), "predicted_N": float(b.predicted_N.mean()),
                        "rmse_N": float(np.sqrt(np.mean((b.measured_N - b.predicted_N) ** 2)))})  # fmt: skip
        near, far = g[g.dz_L < 3], g[g.dz_L >= 3]

        def rmse(x: pd.DataFrame) -> float | None:
            return float(np.sqrt(np.mean((x.measured_N - x.predicted_N) ** 2))) if len(x) else None

        def ratio(x: pd.DataFrame) -> float | None:
            return float(x.measured_N.mean() / x.predicted_N.mean()) if len(x) and x.predicted_N.mean() != 0 else None

        out["c_near_field"][key] = {
            "n_near": int(len(near)), "n_far": int(len(far)),
            "rmse_N_near": rmse(near), "rmse_N_far": rmse(far),
            "mean_measured_over_predicted_near": ratio(near), "mean_measured_over_predicted_far": ratio(far),
            "bins": per,
        }  # fmt: skip
        ground = []
        for lo, hi in zip(H_EDGES[:-1], H_EDGES[1:]):
            b = g[(g.h_over_dz >= lo) & (g.h_over_dz < hi)]
            if len(b) >= 30:
                ground.append({"h_over_dz": [float(lo), float(hi)], "n": int(len(b)), "dz_L_mean": float(b.dz_L.mean()),
                               "measured_N": float(b.measured_N.mean()), "predicted_N": float(b.predicted_N.mean())})  # fmt: skip
        out["b_ground"][key] = ground
        fig_rows.append((key, per, ground))
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n_col = max(1, len(fig_rows))
    fig, axes = plt.subplots(2, n_col, figsize=(4.2 * n_col, 7.0), squeeze=False)
    for ax, (key, _, ground) in zip(axes[1], fig_rows):
        mid = [0.5 * sum(p["h_over_dz"]) for p in ground]
        ax.plot(mid, [p["measured_N"] / p["predicted_N"] for p in ground], "o-", label="measured / model")
        ax.axhline(1.0, color="grey", lw=0.8)
        ax.set_title(key, fontsize=9)
        ax.set_xlabel("h / dz (height above ground / depth)")
        ax.set_ylabel("mean F_z measured / predicted")
        ax.legend(fontsize=8)
    for ax, (key, per, _) in zip(axes[0], fig_rows):
        mid = [0.5 * sum(p["dz_L"]) for p in per]
        ax.plot(mid, [p["measured_N"] for p in per], "o-", label="measured")
        ax.plot(mid, [p["predicted_N"] for p in per], "s--", label="model (identify)")
        ax.axvline(3.0, color="grey", lw=0.8, ls=":")
        ax.set_title(key, fontsize=9)
        ax.set_xlabel("dz / L of the source")
        ax.set_ylabel("mean F_z under the source, N")
        ax.legend(fontsize=8)
    fig.tight_layout()
    args.out.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out / "residual_physics.png", dpi=110)
    out["fits_on_unsaturated_samples"] = fit_candidates(result, logs)
    (args.out / "residual_physics.json").write_text(json.dumps(out, indent=1))
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
