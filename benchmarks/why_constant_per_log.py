"""Does the battery, as the logs record it, explain the residual's constant per vehicle log (issue 35, round 34V)?

Each vehicle log of a saved model's manifest is measured as ``proxplan evaluate`` measures it (the saved model's
measurement and thrust maps) and predicted by the saved model; its CONSTANT is the mean F_z residual over the log
(g). Per log, the covariates the logs hold (each a figure of the whole log):

* ``V_mean`` - mean battery voltage, V; ``V_hover`` - mean Vbat where every motor is in range and the total u is
  within :data:`HOVER_BAND` of the weight, V (within a type, a regression on V relative to the type's mean is
  the same test: the intercept absorbs the mean);
* ``sag`` - mean Vbat less its mean over the log's lowest-thrust tenth, V;
* ``R_int`` - the battery's internal resistance, V/N of total thrust: minus the slope of Vbat on the total u,
  the drain (a slope on time) fitted beside it;
* ``ratio`` - mean PWM*Vbat per newton of u at hover (the firmware map's delivered-per-desired), V/N;
* ``map_ratio`` - the log's u over the type's thrust map of its PWM*Vbat at hover, -;
* ``uV`` - mean of the total u times (Vbat - :data:`V_REF_V`), N V (a thrust error k_V u (V - V_ref));
* ``duration`` - the log's length, s; ``acc_z`` - mean vertical specific force, m/s^2.

The test, stated before the figures were seen: per vehicle type, over TRAIN logs only, ordinary least squares of
the constant on each covariate (one at a time, with an intercept), scored leave-one-FLIGHT-out: the held-out R^2
against the type's held-out mean; its p-value from :data:`PERMUTATIONS` permutations of the covariate across the
type's train logs (seed :data:`SEED`); significant below 0.05 / (covariates x types) (Bonferroni). Each line is
then applied WITHOUT refitting to the test logs: the RMS of the test constants about the type's train mean and
about the line. Within a log: the residual's slope on Vbat and on time (the battery drains during a flight), and
the mass check: a mass error dm gives the residual dm * acc_z (acc_z ~ g at hover), so the constant (in grams)
and dm from the within-log slope on acc_z must agree.

    python benchmarks/why_constant_per_log.py manifests/neural-swarm.yaml --model M.yaml [--json]

(M.yaml: ``proxplan identify manifests/neural-swarm.yaml --out D --save-model M.yaml``.) Nothing here is fitted on
validation or test logs; no constant was set while watching these figures.
"""

from __future__ import annotations

import argparse
import json
from dataclasses import dataclass

import numpy as np
from sklearn.model_selection import LeaveOneGroupOut

from proxplan.identify.data import IdentifyOptions, Model, Predictions
from proxplan.identify.evaluate import GRAMS_PER_N, measurement_from_model
from proxplan.identify.loading import load_units
from proxplan.identify.manifest import load_manifest
from proxplan.identify.thrust_map import IN_RANGE, MotorSamples, motor_limits
from proxplan.physics import GRAVITY_MPS2
from proxplan.physics.model_file import load_model_file

HOVER_BAND = 0.15
"""A sample is at hover when the total u lies within this fraction of the vehicle's weight, -."""
LOW_THRUST_QUANTILE = 0.1
"""The 'lowest-thrust stretch' of the sag: the samples below this quantile of the log's total u, -."""
MIN_HOVER_SAMPLES = 50
"""Fewer hover samples (0.5 s at 100 Hz) leave the hover figures of a log undefined, -."""
V_REF_V = 3.8
"""Reference battery voltage of ``uV``, V: mid-range of the shipped logs (3.4-3.9 V)."""
PERMUTATIONS = 1999
"""Permutations of the covariate per test (p resolution 1/2000), -."""
SEED = 0
"""Seed of the permutations."""
ALPHA = 0.05
"""Family-wise level, before Bonferroni, -."""
COVARIATES = ("V_mean", "V_hover", "sag", "R_int", "ratio", "map_ratio", "uV", "duration", "acc_z")


@dataclass(frozen=True)
class LogFigures:
    """One vehicle log: its constant (g), covariates and within-log slopes."""

    flight: str
    name: str
    type: str
    split: str
    constant_g: float
    covariates: dict[str, float]
    slope_on_V_g_per_V: float  # within-log slope of the residual on Vbat, g/V
    slope_on_t_g_per_s: float  # within-log slope on time since the log's start, g/s
    mass_error_g: float  # dm: the residual (grams-force) = dm acc_z / g, so dm = g x its within-log slope on acc_z, g


def _slope(x: np.ndarray, y: np.ndarray) -> float:
    a = np.column_stack([np.ones_like(x), x - x.mean()])
    return float(np.linalg.lstsq(a, y, rcond=None)[0][1])


def measure(manifest_path: str, model_path: str) -> list[LogFigures]:
    """Every scored vehicle log of the manifest with the saved model (module docstring)."""
    manifest = load_manifest(manifest_path, require_train_and_test=False)
    saved = load_model_file(model_path)
    options, maps, _ = measurement_from_model(saved, model_path)
    data = load_units(manifest, options=IdentifyOptions(measure=options), thrust_maps=maps,
                      thrust_coefficient_samples=False)  # fmt: skip
    vehicles = {t: saved.vehicles.get(t, v) for t, v in data.types.items()}
    model = Model(vehicles=vehicles, thrust_scale=dict(saved.thrust_scales), effects=tuple(saved.effects),
                  options=saved.options)  # fmt: skip
    pred = Predictions()
    out = []
    for u in data.units:
        if not u.scored or not len(u):
            continue
        veh, log = data.logs[(u.flight, u.name)]
        assert log.vbat_V is not None and log.motor_pwm is not None, f"{log.source}: no Vbat/PWM"
        res_g = (u.force_N[:, 2] - pred(u, model)[0][:, 2]) * GRAMS_PER_N
        v, pwm, motor_N = log.vbat_V, log.motor_pwm, log.motor_thrust_N
        total_N, t_s, acc_z = motor_N.sum(axis=1), log.t_s - log.t_s[0], log.accel_mps2[:, 2]
        tmap = maps[u.type]
        in_range = np.all(motor_limits(tmap, MotorSamples(commanded_N=motor_N, pwm=pwm, vbat_V=v)) == IN_RANGE, axis=1)
        weight_N = veh.weight_N
        hover = in_range & (np.abs(total_N - weight_N) < HOVER_BAND * weight_N)
        low = total_N <= np.quantile(total_N, LOW_THRUST_QUANTILE)
        drain = np.linalg.lstsq(np.column_stack([np.ones_like(t_s), t_s, total_N]), v, rcond=None)[0]
        enough = hover.sum() >= MIN_HOVER_SAMPLES
        nan = float("nan")
        cov = {
            "V_mean": float(v.mean()),
            "V_hover": float(v[hover].mean()) if enough else nan,
            "sag": float(v.mean() - v[low].mean()),
            "R_int": float(-drain[2]),
            "ratio": float((pwm * v[:, None])[hover].sum(axis=1).mean() / total_N[hover].mean()) if enough else nan,
            "map_ratio": float(total_N[hover].mean() / tmap.thrust_N(pwm, v).sum(axis=1)[hover].mean()) if enough else nan,
            "uV": float(np.mean(total_N * (v - V_REF_V))),
            "duration": float(t_s[-1]),
            "acc_z": float(acc_z.mean()),
        }  # fmt: skip
        out.append(LogFigures(flight=u.flight, name=u.name, type=u.type, split=u.split,
                              constant_g=float(res_g.mean()), covariates=cov,
                              slope_on_V_g_per_V=_slope(v, res_g), slope_on_t_g_per_s=_slope(t_s, res_g),
                              mass_error_g=GRAVITY_MPS2 * _slope(acc_z, res_g)))  # fmt: skip
    return out


def lofo_r2(c: np.ndarray, x: np.ndarray, flights: np.ndarray) -> float:
    """Held-out R^2 of c ~ a + b x, each flight's logs predicted by the fit without that flight, against the
    held-out mean of c (-)."""
    sse_line = sse_mean = 0.0
    for fit, held in LeaveOneGroupOut().split(x, groups=flights):
        b = np.polyfit(x[fit], c[fit], 1)
        sse_line += float(np.sum((c[held] - np.polyval(b, x[held])) ** 2))
        sse_mean += float(np.sum((c[held] - c[fit].mean()) ** 2))
    return 1.0 - sse_line / sse_mean


def _rms(a: np.ndarray) -> float:
    return float(np.sqrt(np.mean(a**2))) if a.size else float("nan")


def covariate_tests(logs: list[LogFigures]) -> dict[str, dict[str, dict[str, float]]]:
    """Per type and covariate: slope, held-out R^2, permutation p, significance and the test logs' RMS about the
    train mean and about the train line (module docstring)."""
    rng = np.random.default_rng(SEED)
    types = sorted({g.type for g in logs})
    level = ALPHA / (len(COVARIATES) * len(types))
    out: dict[str, dict[str, dict[str, float]]] = {}
    for t in types:
        train = [g for g in logs if g.type == t and g.split == "train"]
        test = [g for g in logs if g.type == t and g.split == "test"]
        c_all = np.array([g.constant_g for g in train])
        fl_all = np.array([g.flight for g in train])
        out[t] = {}
        for k in COVARIATES:
            x_all = np.array([g.covariates[k] for g in train])
            ok = np.isfinite(x_all)
            c, x, fl = c_all[ok], x_all[ok], fl_all[ok]
            r2 = lofo_r2(c, x, fl)
            perm = np.array([lofo_r2(c, rng.permutation(x), fl) for _ in range(PERMUTATIONS)])
            p = float((1 + np.sum(perm >= r2)) / (1 + PERMUTATIONS))
            line = np.polyfit(x, c, 1)
            xt = np.array([g.covariates[k] for g in test])
            ct = np.array([g.constant_g for g in test])[np.isfinite(xt)]
            xt = xt[np.isfinite(xt)]
            out[t][k] = {"logs": int(ok.sum()), "slope_g_per_unit": float(line[0]), "lofo_r2": r2, "p": p,
                         "significant": bool(p < level), "level": level,
                         "test_rms_about_train_mean_g": _rms(ct - c.mean()),
                         "test_rms_about_line_g": _rms(ct - np.polyval(line, xt)), "test_logs": int(ct.size)}  # fmt: skip
    return out


def within_log(logs: list[LogFigures]) -> dict[str, dict[str, dict[str, float]]]:
    """Per split and type: the within-log slopes on Vbat and time, and the mass check (module docstring)."""
    out: dict[str, dict[str, dict[str, float]]] = {}
    for split in ("train", "test"):
        for t in sorted({g.type for g in logs}):
            sel = [g for g in logs if g.type == t and g.split == split]
            if not sel:
                continue
            c = np.array([g.constant_g for g in sel])
            sv = np.array([g.slope_on_V_g_per_V for g in sel])
            st = np.array([g.slope_on_t_g_per_s for g in sel])
            dm = np.array([g.mass_error_g for g in sel])
            out.setdefault(split, {})[t] = {
                "logs": len(sel), "constant_rms_g": _rms(c),
                "slope_on_V_median_g_per_V": float(np.median(sv)), "slope_on_V_positive": int(np.sum(sv > 0)),
                "slope_on_t_median_g_per_10s": float(10 * np.median(st)), "slope_on_t_positive": int(np.sum(st > 0)),
                "mass_error_median_g": float(np.median(dm)),
                "mass_constant_corr": float(np.corrcoef(dm, c)[0, 1]),
                "rms_constant_less_mass_g": _rms(c - dm),
            }  # fmt: skip
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("manifest")
    ap.add_argument("--model", required=True, help="a model saved by identify --save-model")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    logs = measure(args.manifest, args.model)
    tests, within = covariate_tests(logs), within_log(logs)
    if args.json:
        print(json.dumps({"covariates": tests, "within_log": within}, indent=1))
        return
    for t, rows in tests.items():
        c = np.array([g.constant_g for g in logs if g.type == t and g.split == "train"])
        print(f"\n{t}: {c.size} train logs, constant {c.mean():+.2f} g mean, {c.std(ddof=1):.2f} g sd")
        print("| covariate | logs | slope [g/unit] | held-out R2 | perm p | test RMS about mean / line [g] |")
        for k, r in rows.items():
            sig = " SIGNIFICANT" if r["significant"] else ""
            print(f"| {k} | {r['logs']} | {r['slope_g_per_unit']:+.3g} | {r['lofo_r2']:+.3f} | {r['p']:.4f}{sig} | "
                  f"{r['test_rms_about_train_mean_g']:.2f} / {r['test_rms_about_line_g']:.2f} ({r['test_logs']}) |")  # fmt: skip
    for split, per in within.items():
        for t, w in per.items():
            print(f"\n{split} {t} within-log: " + ", ".join(f"{k} {v:.3g}" for k, v in w.items()))


if __name__ == "__main__":
    main()
