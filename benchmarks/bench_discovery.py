"""Speed of ``proxplan identify`` WITH the discovery of unnamed terms on one hour of 100 Hz logs of
two vehicles (issue 13: < 60 s).

Generates (untimed) ``--flights`` x ``--minutes-per-flight`` of measurement-level synthetic logs of
two small quads, the lower one sweeping under the upper one, with a hidden force no library effect
names (F_z = -0.6 N s/m |v_rel,xy| exp(-(r / 0.8 L)^2 - dz / 6 L) under a source: a swept wake).
Times, in the same run: the pipeline without discovery (baseline), the pipeline with it, and the
discovery stage alone; prints the ratios and what was discovered.

    python benchmarks/bench_discovery.py [--minutes-per-flight 10] [--flights 6] [--data DIR]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import yaml

from proxplan.identify import (
    IdentifyOptions,
    discover_terms,
    run_identify,
    synthetic_logs,
    validation_split,
    write_synthetic_manifest,
)
from proxplan.physics import BUILTIN_VEHICLES


def swept_wake(inputs):
    force, torque = np.zeros((inputs.n_samples, 3)), np.zeros((inputs.n_samples, 3))
    for src in inputs.sources:
        dz, r = -src.offsets_m[:, 2], np.hypot(src.offsets_m[:, 0], src.offsets_m[:, 1])
        v_rel = inputs.velocity_mps - src.velocity_mps
        size = src.vehicle.size_m
        k = np.where(dz > 0, np.exp(-((r / (0.8 * size)) ** 2) - dz / (6 * size)), 0.0)
        force[:, 2] -= 0.6 * np.hypot(v_rel[:, 0], v_rel[:, 1]) * k
    return force, torque


def _paths(t: np.ndarray, phase: float) -> dict[str, np.ndarray]:
    a = np.column_stack([0.3 * np.sin(t * 1.5 + phase), 0.15 * np.cos(t + phase), 1.5 + 0 * t])
    b = np.column_stack(
        [0.3 * a[:, 0] + 0.12 * np.sin(0.7 * t), 0.3 * a[:, 1] + 0.06 * np.sin(0.9 * t), 1.0 - 0.25 * np.sin(t)]
    )
    return {"a": a, "b": b}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes-per-flight", type=float, default=10.0, help="length of each synthetic flight, min")
    ap.add_argument("--flights", type=int, default=6, help="number of flights (the last two are test flights)")
    ap.add_argument("--data", type=Path, default=None, help="directory to keep (or reuse) the generated logs")
    args = ap.parse_args()
    veh = BUILTIN_VEHICLES["small-quad"]
    with tempfile.TemporaryDirectory() as tmp:
        root = args.data or Path(tmp)
        root.mkdir(parents=True, exist_ok=True)
        manifest = root / "manifest.yaml"
        t = np.arange(0.0, 60.0 * args.minutes_per_flight, 0.01)
        if not manifest.exists():
            flights = [
                (f"f{k}", "test" if k >= args.flights - 2 else "train", synthetic_logs(
                    {"a": veh, "b": veh}, _paths(t, 0.7 * k), t, hidden_wrench=swept_wake, accel_noise_mps2=0.02, seed=k
                ))
                for k in range(args.flights)
            ]  # fmt: skip
            write_synthetic_manifest(root, flights, "small-quad")
        n_flights = len(yaml.safe_load(manifest.read_text())["flights"])
        print(
            f"{n_flights} flights x {t.size} samples x 2 vehicles = {n_flights * t.size / 3.6e5:.2f} h of 100 Hz logs"
        )

        t0 = time.perf_counter()
        plain = run_identify(manifest, options=IdentifyOptions(discover=False), thrust_summary=False)
        t_plain = time.perf_counter() - t0
        t0 = time.perf_counter()
        full = run_identify(manifest, options=IdentifyOptions(discover=True), thrust_summary=False)
        t_full = time.perf_counter() - t0
        train = [u for u in full.units if u.split == "train" and len(u)]
        test = [u for u in full.units if u.split == "test" and len(u)]
        t0 = time.perf_counter()
        discover_terms(*validation_split(train)[:2], replace(plain.final_model), test=test)
        t_disc = time.perf_counter() - t0
        print(f"identify without discovery (baseline): {t_plain:.1f} s")
        print(
            f"identify with discovery:               {t_full:.1f} s  ({t_full / t_plain:.2f}x baseline; target < 60 s)"
        )
        print(f"discovery stage alone:                 {t_disc:.1f} s  ({t_disc / t_plain:.2f}x baseline)")
        print(f"test F_z RMSE: library only {plain.after.rmse_fz_N:.5f} N, with discovery {full.after.rmse_fz_N:.5f} N")
        for e in full.discovered:
            print(
                f"  {e['name']} {e['channel']}: selected={e['selected']} gain_validation={e['gain_validation']:.3f} {e['formula']}"
            )


if __name__ == "__main__":
    main()
