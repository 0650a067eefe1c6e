"""Markdown report and PNG plots of an identification run (``proxplan identify --out DIR``).

Files written into DIR (each atomically, temp file + rename):
``report.md``, ``measured_vs_predicted.png`` (test F_z over time, before and after),
``residual_vs_features.png`` (final test F_z residual vs dz, r, height above ground),
``effects.png`` (test RMSE of F_z and yaw torque per candidate effect, before/after),
``thrust_coefficient.png`` (seed 001 RLS history of the S1-25 parameters, when available).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np

from proxplan.fileio import atomic_write_text, save_figure
from proxplan.identify.data import predict
from proxplan.identify.per_flight import COVERAGE_LEVEL
from proxplan.identify.pipeline import IdentifyResult
from proxplan.identify.residuals import sample_features


def _save(fig, path: Path) -> None:
    save_figure(fig, path, dpi=110, bbox_inches="tight")


def write_plots(result: IdentifyResult, out_dir: Path) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    test = [u for u in result.units if u.split == "test" and u.scored and len(u)]
    # 1. measured vs predicted F_z, the test vehicle with the strongest base disturbance
    strength = [float(np.std(u.force_N[:, 2])) if u.source_types else 0.0 for u in test]
    unit = test[int(np.argmax(strength))]  # the most disturbed test vehicle (measured F_z spread)
    if len(unit) > 6000:  # plot a 60 s window around its strongest disturbance
        k = int(np.argmin(unit.force_N[:, 2]))
        unit = unit.take(np.arange(max(0, k - 3000), min(len(unit), k + 3000)))
    fb, _ = predict(unit, result.base_model)
    fa, _ = predict(unit, result.final_model)
    fig, ax = plt.subplots(figsize=(10, 4))
    t = unit.t_s - unit.t_s[0]
    ax.plot(t, unit.force_N[:, 2], lw=0.8, color="k", label="measured (S0-11)")
    ax.plot(t, fb[:, 2], lw=1.0, label="model before")
    ax.plot(t, fa[:, 2], lw=1.0, label="after (calibrated + " + (", ".join(result.selected) or "no effect") + ")")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("F_z [N]")
    ax.set_title(f"test flight {unit.flight}, vehicle {unit.name} ({unit.type})")
    ax.legend(fontsize=8)
    p = out_dir / "measured_vs_predicted.png"
    _save(fig, p)
    plt.close(fig)
    written.append(p)
    # 2. residual vs features
    res: list[np.ndarray] = []
    feats: dict[str, list[np.ndarray]] = {}
    from proxplan.identify.data import subsample

    for u in subsample(test, 50000):
        f, _ = predict(u, result.final_model)
        res.append(u.force_N[:, 2] - f[:, 2])
        for key, v in sample_features(u.height_above_ground_m, u.velocity_mps, list(u.source_offsets_m)).items():
            feats.setdefault(key, []).append(v)
    r = np.concatenate(res)
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.8), sharey=True)
    for ax, key in zip(axes, ("dz_m", "r_m", "height_above_ground_m")):
        x = np.concatenate(feats[key])
        step = max(1, len(x) // 20000)
        ax.scatter(x[::step], r[::step], s=2, alpha=0.3)
        ax.set_xlabel(key.replace("_m", " [m]"))
        ax.axhline(0.0, color="k", lw=0.5)
    axes[0].set_ylabel("F_z residual after [N]")
    fig.suptitle("test-flight residual of F_z vs features")
    p = out_dir / "residual_vs_features.png"
    _save(fig, p)
    plt.close(fig)
    written.append(p)
    # 3. effects before/after
    first = [tr for tr in result.trials if tr.test is not None]  # each candidate with the recalibration, alone
    labels = ["before", "calibrated"] + [tr.name for tr in first] + ["after"]
    fz = (
        [result.before.rmse_fz_N, result.calibrated.rmse_fz_N]
        + [tr.test.rmse_fz_N for tr in first if tr.test is not None]
        + [result.after.rmse_fz_N]
    )
    tz = (
        [result.before.rmse_tz_Nm, result.calibrated.rmse_tz_Nm]
        + [tr.test.rmse_tz_Nm for tr in first if tr.test is not None]
        + [result.after.rmse_tz_Nm]
    )
    fig, axes = plt.subplots(1, 2, figsize=(13, 4))
    for ax, vals, name in zip(axes, (fz, tz), ("test RMSE F_z [N]", "test RMSE yaw torque [N m]")):
        colors = ["tab:red", "tab:orange"] + ["tab:gray"] * len(first) + ["tab:green"]
        ax.bar(range(len(vals)), vals, color=colors)
        ax.set_xticks(range(len(vals)), labels, rotation=40, ha="right", fontsize=8)
        ax.set_ylabel(name)
    fig.suptitle("each candidate effect alone on the reference model (jointly recalibrated), before and after")
    p = out_dir / "effects.png"
    _save(fig, p)
    plt.close(fig)
    written.append(p)
    # 4. RLS history
    hist = {t: d["_rls_history"] for t, d in result.thrust_coefficient.items() if "_rls_history" in d}
    if hist:
        from proxplan.identify.thrust_rls import REGRESSOR_NAMES

        fig, axes = plt.subplots(2, 3, figsize=(12, 5.5))
        for t, h in hist.items():
            for k, ax in enumerate(axes.ravel()):
                ax.plot(h[:, k], lw=0.8, label=t)
                ax.set_title(REGRESSOR_NAMES[k], fontsize=9)
        axes[0, 0].legend(fontsize=7)
        fig.suptitle("seed 001 RLS (S1-28..30, forgetting 0.99) on train logs, decimated samples")
        p = out_dir / "thrust_coefficient.png"
        _save(fig, p)
        plt.close(fig)
        written.append(p)
    return written


def exclusion_lines(exclusions: dict) -> list[str]:
    """One markdown bullet per flight with the non-zero exclusion counts of each vehicle."""
    lines = []
    for flight, per in exclusions.items():
        parts = "; ".join(
            f"{n}: "
            + ", ".join(
                [f"{k} {v}" for k, v in e.items() if isinstance(v, int) and not isinstance(v, bool) and v]
                + [f"thrust {e['thrust_source']}"] * ("thrust_source" in e)
                + _clock(e)
            )  # fmt: skip
            for n, e in per.items()
        )
        lines.append(f"- {flight}: {parts}")
    return lines


def _clock(e: dict) -> list[str]:
    """How a vehicle's clock was set (identify.formats.registry.align_log), when not its own log clock."""
    how = e.get("alignment")
    if how == "mocap":
        return [f"clock {e['time_offset_s']:+.3f} s +- {e['alignment_error_s']:.3f} s (cross-correlated with mocap)"]
    if how == "manifest offset":
        return [f"clock {e['time_offset_s']:+.3f} s (manifest)"]
    return []


def motor_check_lines(check: dict) -> list[str]:
    """Markdown of the motor-lag self-check (:func:`proxplan.identify.motor_check.motor_lag_check`)."""
    if not check or not check.get("types"):
        return []
    lines = ["## Motor lag check (free-flight F_z spread by motor time constant)", "",
             f"Declared `motor_thrust: {check['motor_thrust']}`. Spread = RMS of F_z about each log's mean on "
             "free-flight samples (no source overhead, above 0.3 m, motors in range).", "",
             "| type | free samples | declared tau [s] | spread [mN] | best tau [s] | spread [mN] | verdict |",
             "|---|---|---|---|---|---|---|"]  # fmt: skip
    for t, e in check["types"].items():
        lines.append(f"| {t} | {e['n_free_samples']} | {e['declared_tau_s']:g} | {1000 * e['spread_declared_N']:.2f} | "
                     f"{e['best_tau_s']:g} | {1000 * e['spread_best_N']:.2f} | "
                     f"{'**warning**' if e['warning'] else 'agrees'} |")  # fmt: skip
    return lines + [""] + [f"- **warning**: {w}" for w in check.get("warnings", [])] + [""]


def command_hold_lines(holds: dict) -> list[str]:
    """Markdown of how each type's logged command runs between samples (the ``command_hold`` JSON of
    :mod:`proxplan.identify.command_check`)."""
    if not holds:
        return []
    lines = ["## Command hold (how the logged motor command runs between samples into the motor lag)", "",
             "p = 0: held to the next sample; 1: linear to it. Spread = RMS about each log's mean on free-flight "
             "samples; t = mean over flights of 0.5 ln(SSE_p / SSE_0) over its standard error.", "",
             "| type | flights | p taken | F_z spread p=0 / 1 [mN] | roll torque spread p=0 / 1 [mN m] | t (p=1: F_z, tau_x, tau_y) | why |",
             "|---|---|---|---|---|---|---|"]  # fmt: skip
    for t, h in holds.items():
        sp, ts = h.get("spread") or {}, (h.get("t_stat") or {}).get("1", {})
        fz = f"{1000 * sp['0']['F_z']:.2f} / {1000 * sp['1']['F_z']:.2f}" if "0" in sp and "1" in sp else "-"
        tx = f"{1000 * sp['0']['tau_x']:.3f} / {1000 * sp['1']['tau_x']:.3f}" if "0" in sp and "1" in sp else "-"
        tt = ", ".join(f"{v:+.1f}" for v in ts.values()) if ts else "-"
        lines.append(f"| {t} | {h['n_flights']} | {h['interpolation']:g} | {fz} | {tx} | {tt} | {h['reason']} |")
    return lines + [""]


def limit_lines(saturation: dict) -> list[str]:
    """Markdown table of the samples with a motor at its ceiling / floor per vehicle (the
    ``measurement.saturation`` JSON of :func:`proxplan.identify.loading.measurement_summary`)."""
    lines = ["| vehicle | thrust from | at the ceiling (samples, share) | at the floor (samples, share) |",
             "|---|---|---|---|"]  # fmt: skip
    for name, s in saturation.items():
        lines.append(f"| {name} | {s['thrust_source']} | {s['saturated_samples']} ({s['saturated_fraction']:.3f}) | "
                     f"{s['floored_samples']} ({s['floored_fraction']:.3f}) |")  # fmt: skip
    return lines


def selection_lines(result: IdentifyResult) -> list[str]:
    """Markdown of the library effects' selection: how flights were held out (a fallback said), which start
    won, and every candidate's held-out gain, inclusion probability and verdict."""
    sel = result.selection
    lines = ["", "## Library effects (fitted on train flights, judged by flights held out, scored on test)", "",
             f"{result.validation}.", ""]  # fmt: skip
    if result.fallback:
        lines += [f"**Selection fell back**: {result.validation}.", ""]
    if sel:
        other = sel.get("other_start_heldout_mse")
        lines += [f"Selection around the **{sel['start']}** model (held-out score {sel['heldout_log_mse']:.4g}"
                  + (f"; the other start {other:.4g}" if other is not None else "") + "; lower is better). "
                  "A candidate is kept when its held-out gain (sum over channels of ln(MSE without / MSE with), every "
                  "flight predicted by a fit without it) exceeds z flight-to-flight standard errors (one-sided "
                  "Bonferroni at 5 %) AND it is chosen in at least the stated share of half-samples of the flights "
                  "(stability selection). Test flights only report.", ""]  # fmt: skip
        channels = sel.get("channel_heldout_mse") or {}
        if channels:
            per = "; ".join(f"{t}: " + ", ".join(f"{c} {'n/a' if m is None else f'{m:.3g}'}" for c, m in ms.items())
                            for t, ms in channels.items())  # fmt: skip
            lines += ["Held-out error per channel, in noise units (1: predicted to the noise; the delivered fit weighs "
                      f"each channel by 1 / max(this, 1)): {per}.", ""]  # fmt: skip
    lines += ["| round | effect | params | RMSE F_z test [N] | held-out gain alone (R +- SE) | inclusion | kept | why |",
              "|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for tr in result.trials:
        params = ", ".join(f"{k}={v:.4g}" for k, v in tr.params.items())
        g = tr.gain_alone
        gain = "n/a" if g is None else f"{g.mean:+.3g} +- {g.se:.2g}"
        test = _fmt(tr.test.rmse_fz_N) if tr.test is not None else "n/a"
        lines.append(f"| {tr.round} | {tr.name} | {params} | {test} | {gain} | {tr.inclusion:.0%} | "
                     f"{'yes' if tr.selected else ''} | {tr.reason} |")  # fmt: skip
    for kept, rivals in (sel.get("indistinguishable") or {}).items():
        lines += ["", f"**{kept}** was kept, but these flights cannot tell it from {', '.join(sorted(rivals))}: "
                  "each predicts the held-out flights about as well (head-to-head test in the table). Flights that "
                  "separate their causes (other separations, heights, speeds) would decide."]  # fmt: skip
    return lines


def calibration_lines(cal) -> list[str]:
    """Markdown of the MAP calibration: every parameter with its posterior sigma, prior, move in prior sigmas,
    and whether the data informed it or moved it suspiciously far (:mod:`proxplan.identify.priors`)."""
    lines = ["", "## Calibrated parameters (MAP with priors, train flights; proxplan.identify.priors)", "",
             "| parameter | value | posterior std | prior (center, sigma) | moved [prior sigmas] | data informed it |",
             "|---|---|---|---|---|---|"]  # fmt: skip
    report = cal.prior_report()
    for n, v, s in zip(cal.names, cal.values, cal.std):
        r = report.get(n)
        std = _fmt(float(s)) if np.isfinite(s) else "not identifiable"
        if r is None:
            lines.append(f"| {n} | {v:.5g} | {std} | held | - | - |")
            continue
        prior = f"{r['prior_center']:.4g}, {r['prior_sigma']:.3g}" + (" (of ln)" if r["prior_log"] else "")
        move = f"{r['move_sigmas']:+.2f}" + (" **large: a missing effect?**" if r["large_move"] else "")
        lines.append(
            f"| {n} | {v:.5g} | {std} | {prior} | {move} | {'yes' if r['informed'] else 'no (stays at its prior)'} |"
        )
    lines += ["", "Thrust scales are nuisance parameters (they keep a thrust-sensor error out of the aerodynamic "
              "parameters); with `thrust_bias` in the options they are fitted beside every candidate and carried "
              "into the model."]  # fmt: skip
    return lines


def band_lines(bands: Mapping[str, Mapping], title: str = "What the model cannot predict") -> list[str]:
    """Markdown table: per set, the F_z residual's RMSE below and above 1 Hz (grams) and how often the measured
    force falls inside the model's 90 % interval (proxplan.identify.spread)."""
    lines = [f"## {title}", "",
             "The residual split at 1 Hz (zero-phase low-pass): a quasi-steady model of the mean jet cannot follow "
             "the fast part. Constant per log: the RMS of each vehicle log's mean residual (part of the slow "
             "part; no model of the air predicts it, and it follows none of the battery figures the logs hold: "
             "docs/identify.md, stop 72). Coverage: the share of samples inside the saved 90 % interval (target 85-95 %); "
             f"beside it its {100 * COVERAGE_LEVEL:.0f} % interval with the FLIGHT as the unit (samples of one flight share its constant: "
             "a ratio estimator over flights, proxplan.identify.per_flight), and whether 90 % lies inside it "
             "(a set of few flights whose interval holds 90 % is no miss).", "",
             "| set | below 1 Hz [g] | above 1 Hz [g] | constant per log [g] | 90 % interval coverage "
             f"| its {100 * COVERAGE_LEVEL:.0f} % interval (flights) | holds 90 % | flights | samples |",
             "|---|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for k, b in bands.items():
        cov = "n/a" if b["coverage_90"] is None else f"{100 * b['coverage_90']:.1f} %"
        ci = b.get("coverage_90_interval")
        ci_txt = "n/a" if ci is None else f"{100 * ci[0]:.1f}-{100 * ci[1]:.1f} %"
        holds = b.get("coverage_90_holds")
        holds_txt = "n/a" if holds is None else ("yes" if holds else "NO")
        flights = b.get("n_flights")
        lines.append(
            f"| {k} | {_grams(b['rmse_fz_below_1Hz_g'])} | {_grams(b['rmse_fz_above_1Hz_g'])} | "
            f"{_grams(b.get('rmse_fz_constant_per_log_g'))} | {cov} | {ci_txt} | {holds_txt} | "
            f"{'n/a' if flights is None else flights} | {b['n_samples']} |"
        )
    return lines + [""]


def _grams(x: float | None) -> str:
    return "n/a" if x is None else f"{x:.2f}"


def _fmt(x: float | None, digits: int = 4) -> str:
    return "n/a" if x is None else f"{x:.{digits}g}"


def markdown(result: IdentifyResult, *, manifest: str = "", plots: Sequence[Path] = ()) -> str:
    b, c, a = result.before, result.calibrated, result.after
    lines = [f"# proxplan identify — {manifest}", ""]
    lines += ["## Test-flight error before and after", "",
              "| model | RMSE F_z [N] | RMSE torque [N m] | RMSE yaw torque [N m] | samples |", "|---|---|---|---|---|"]  # fmt: skip
    for name, e in (("before (model as given)", b), ("calibrated", c), ("after (calibrated + effects)", a)):
        lines.append(
            f"| {name} | {_fmt(e.rmse_fz_N)} | {_fmt(e.rmse_torque_Nm)} | {_fmt(e.rmse_tz_Nm)} | {e.n_samples} |"
        )
    cut = 100.0 * (1.0 - a.rmse_fz_N / b.rmse_fz_N) if b.rmse_fz_N > 0 else 0.0
    lines += ["", f"Selected effects: **{', '.join(result.selected) or 'none'}**. F_z error cut by {cut:.1f} %.", ""]
    undecided = result.undecided()
    if undecided:
        lines += ["Not decided by these flights (every held-out flight gained, too few flights to pass the test):", ""]
        lines += [f"- {line}" for line in undecided] + [""]
    one_flight = result.one_flight()
    if one_flight:
        lines += ["Not testable on these flights (what it changes lies mostly on one flight; not kept):", ""]
        lines += [f"- {line}" for line in one_flight] + [""]
    lines += ["## Per vehicle (test flights, RMSE F_z [N])", "", "| vehicle | before | calibrated | after | samples |",
              "|---|---|---|---|---|"]  # fmt: skip
    for name, pv in result.per_vehicle.items():
        lines.append(f"| {name} | {_fmt(pv['rmse_fz_N_before'])} | {_fmt(pv['rmse_fz_N_calibrated'])} | "
                     f"{_fmt(pv['rmse_fz_N_after'])} | {pv['n_samples']} |")  # fmt: skip
    lines += ["", "## Measurement (delivered motor thrust)", ""]
    lines += limit_lines(result.measurement_json()["saturation"])
    lines += [""] + motor_check_lines(result.motor_lag_check)
    lines += command_hold_lines({t: h.to_dict() for t, h in result.command_hold.items()})
    lines.append("")
    for t, m in result.thrust_maps.items():
        lines.append(f"- {t}: f = P(pwm Vbat), coefficients {', '.join(f'{c:.4g}' for c in m.coef)}; "
                     f"ceiling {m.x_max_V:.3f} V, max {m.max_thrust_N:.4g} N per motor, RMS {m.rms_N:.2g} N, R2 {m.r2:.4f}")  # fmt: skip
    lines += [f"- note: {n}" for n in result.notes]
    if result.bands:
        lines += [""] + band_lines(result.bands, "What the model cannot predict (test flights)")
    lines += selection_lines(result)
    if result.calibration is not None:
        lines += calibration_lines(result.calibration)
    lines += [
        "",
        "## Residual analysis (final model, test flights, F_z)",
        "",
        "| feature | pearson | eta |",
        "|---|---|---|",
    ]
    for corr in result.correlations:
        lines.append(f"| {corr.feature} | {corr.pearson:.3f} | {corr.eta:.3f} |")
    if result.unexplained:
        u = result.unexplained
        lines += [
            "",
            f"**Unexplained residual**: it still correlates with `{u['feature']}` (pearson {u['pearson']:.2f}, eta {u['eta']:.2f}); no effect of the library removed it.",
        ]
    if result.discovered:
        lines += ["", "## Discovered terms (ensemble sparse regression over half-samples of the flights, kept by "
                  "flights held out; proxplan.identify.discovery)", "",
                  "| channel | feature | family | inclusion (term / stood for / its group) | held-out gain R (t, needs) | kept | formula |",
                  "|---|---|---|---|---|---|---|"]  # fmt: skip
        for e in result.discovered:
            g = e["heldout_gain"]
            gain = "not tested" if g is None else f"{g['mean_gain']:+.3g} ({_fmt(g['t'], 3)}, > {g['z_required']:.2f})"
            feature = e["feature"] + refined_words(e.get("refined"), e.get("sibling_merge")) + split_words(e)
            lines.append(f"| {e['channel']} | {feature} | {e['family']} | {e['inclusion_probability']:.0%} / "
                         f"{e['represented_probability']:.0%} / {e['group_inclusion_probability']:.0%} | {gain} | {'yes' if e['selected'] else 'no'} | "
                         f"{e['formula'] or '-'} |")  # fmt: skip
    v = result.validity
    lines += ["", "## Validity", "", f"Samples below a source (r < 3 L): {v['samples_below_a_source']}; in the model's zone dz > 3 L: "
              f"{v['samples_in_valid_zone']} ({_fmt(v['fraction_valid'], 3)}). {v['note']}.", "",
              "| test samples below a source | RMSE F_z before [N] | after [N] |", "|---|---|---|",
              f"| in the valid zone dz > 3 L | {_fmt(v['rmse_fz_N_valid_zone']['before'])} | {_fmt(v['rmse_fz_N_valid_zone']['after'])} |",
              f"| inside 3 L (outside validity) | {_fmt(v['rmse_fz_N_inside_3L']['before'])} | {_fmt(v['rmse_fz_N_inside_3L']['after'])} |"]  # fmt: skip
    if result.thrust_coefficient:
        lines += ["", "## Thrust coefficient (seed 001, S1-25 LS fit on train logs)", ""]
        for t, d in result.thrust_coefficient.items():
            params = ", ".join(f"{k}={val:.3g}±{d['ls_std'][k]:.1g}" for k, val in d["ls"].items())
            lines.append(f"- {t}: {params}; R² {d['r2']:.2f} over {d['n_samples']} samples")
    lines += ["", "## Excluded samples (quality checks)", ""]
    lines += exclusion_lines(result.exclusions)
    lines += ["", "## Plots", ""] + [f"![{p.stem}]({p.name})" for p in plots]
    return "\n".join(lines) + "\n"


def _feature_of(key: str) -> str:
    return key.rsplit("*", 1)[1]


def refined_words(r: dict | None, sibling: dict | None = None) -> str:
    """What the refinement of a kept term's scales (proxplan.identify.refine) did, in words for its report row:
    ``r`` the refinement reported for it, ``sibling`` the search of its kept siblings as one term where that was
    refused (the JSON of :class:`proxplan.identify.refine.Refined`)."""
    words = ""
    if sibling is not None:
        words += (
            f" (kept beside its siblings: {' + '.join(_feature_of(k) for k in sibling['replaces'])} together "
            f"better on flights held out than one term at {_feature_of(sibling['key'])}, t {_fmt(sibling['test']['t'], 3)} "
            f"> {sibling['test']['z_required']:.2f})"
        )
    if r is None:
        return words
    t, z = _fmt(r["test"]["t"], 3), f"{r['test']['z_required']:.2f}"
    replaces = r.get("replaces") or [r["from"]]
    if r.get("merged") and r["accepted"]:
        return words + (
            f" (one term for {' + '.join(_feature_of(k) for k in replaces)}: the grid terms together not better on "
            f"flights held out, t {t}, needs > {z})"
        )
    if r.get("merged"):
        return words + (
            f" (kept beside its siblings: {' + '.join(_feature_of(k) for k in replaces)} together better on flights "
            f"held out than one term at {_feature_of(r['key'])}, t {t} > {z})"
        )
    if r["accepted"]:
        return words + f" (scales refined from {_feature_of(r['from'])}, t {t} > {z})"
    return words + (
        f" (scales searched, best {_feature_of(r['key'])}: not better on flights held out, t {t}, needs > {z})"
    )


def split_words(entry: dict) -> str:
    """Which form of a kept term (one coefficient, or one per target type: proxplan.identify.type_split) was
    kept, in words for its report row (``entry`` one of :attr:`IdentifyResult.discovered`)."""
    split = entry.get("type_split")
    if split is None or not entry.get("selected"):
        return ""
    one, per = split["test_one_coefficient"], split["test_per_type"]
    tests = (
        "" if one is None or per is None else f", held-out t {_fmt(per['t'], 3)} per type, {_fmt(one['t'], 3)} with one"
    )
    if entry.get("target_type"):
        return f" on {entry['target_type']} only (one coefficient per target type{tests})"
    return f" (one coefficient for {', '.join(split['types'])}{tests})"


def write_report(result: IdentifyResult, out_dir: str | Path, *, manifest: str = "") -> Path:
    """Write plots and ``report.md`` into ``out_dir``; returns the report path."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    plots = write_plots(result, out)
    path = out / "report.md"
    atomic_write_text(path, markdown(result, manifest=manifest, plots=plots))
    return path
