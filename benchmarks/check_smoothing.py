"""How much of a clean generated set's residual is the measurement's own smoothing (issue 35, stop 43)?

The measured wrench is the Savitzky-Golay fit of the true one over the measurement's window; the model
predicts from positions smoothed alike, f(S(x)), not S(f(x)). This script takes the discovery benchmark's
CLEAN twin of a draw (no undeclared effect; :mod:`bench_discovery`), loads it WITHOUT the correction
(``IdentifyOptions(smoothed_prediction=False)``), predicts with the prior model and the generator's own
thrust errors (so nothing is fitted), and regresses the residual on S(p) - p per channel. A coefficient
near 1 with a large share explained says the residual IS the smoothing (a coefficient is fitted only to
show it is 1: the correction identify applies has none).

    python benchmarks/check_smoothing.py [--seeds 13 15 17] [--json]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

CHANNELS = ("F_z", "torque_x", "torque_y", "torque_z")


def check(seed: int, root: Path) -> dict[str, dict[str, float]]:
    """Per channel: RMS of the residual and of S(p) - p (N or N m), the regression coefficient and the share
    of the residual's variance S(p) - p explains, on the clean twin of draw ``seed``."""
    import bench_discovery as bench

    from proxplan.identify.data import IdentifyOptions, Model, predict
    from proxplan.identify.loading import load_units, smoothing_of_prediction
    from proxplan.identify.manifest import load_manifest
    from proxplan.identify.measure import MeasureOptions
    from proxplan.physics import ModelOptions

    spec = bench.draw_spec(seed, bench.FAMILIES[seed % len(bench.FAMILIES)])
    manifest = bench.make_set(spec, root / f"clean_{seed}", None)
    data = load_units(load_manifest(manifest), options=IdentifyOptions(smoothed_prediction=False),
                      thrust_coefficient_samples=False)  # fmt: skip
    truth = Model(vehicles=data.types, thrust_scale={t: 1.0 / (1.0 + e) for t, e in spec.thrust_error.items()})
    prior = Model(vehicles=data.types, options=ModelOptions())
    residual, smoothing = [], []
    for u in data.units:
        if not u.scored or not u.source_types:
            continue
        force, torque = predict(u, truth)
        with_s = smoothing_of_prediction(u, data.logs[(u.flight, u.name)][1], prior, MeasureOptions())
        residual.append(np.column_stack([u.force_N[:, 2] - force[:, 2], u.torque_Nm - torque]))
        smoothing.append(np.column_stack([with_s.smoothing_force_N[:, 2], with_s.smoothing_torque_Nm]))
    r, d = np.concatenate(residual), np.concatenate(smoothing)
    out = {}
    for k, name in enumerate(CHANNELS):
        coef = float(d[:, k] @ r[:, k] / max(float(d[:, k] @ d[:, k]), 1e-300))
        explained = 1.0 - float(np.mean((r[:, k] - coef * d[:, k]) ** 2) / max(float(np.mean(r[:, k] ** 2)), 1e-300))
        out[name] = {"residual_rms": float(np.sqrt(np.mean(r[:, k] ** 2))),
                     "smoothing_rms": float(np.sqrt(np.mean(d[:, k] ** 2))), "coefficient": coef,
                     "explained": explained}  # fmt: skip
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[13, 15, 17], help="draws whose clean twin is checked")
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        results = {seed: check(seed, Path(tmp)) for seed in args.seeds}
    if args.json:
        print(json.dumps(results, indent=1))
        return 0
    for seed, per in results.items():
        for name, v in per.items():
            unit = "mN" if name == "F_z" else "mN m"
            print(f"seed {seed:>3} {name:9} residual {1e3 * v['residual_rms']:8.4f} {unit}, S(p) - p "
                  f"{1e3 * v['smoothing_rms']:8.4f} {unit}, coefficient {v['coefficient']:6.3f}, "
                  f"explains {v['explained']:6.1%}")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
