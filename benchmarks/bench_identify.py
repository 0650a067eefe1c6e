"""Speed of ``proxplan identify`` (issue 8: < 30 s) and ``proxplan evaluate`` (issue 13: < 15 s) on one
hour of 100 Hz logs of two vehicles.

Generates (untimed) 6 flights x 10 min x 2 vehicles of synthetic logs with a hidden near_field
effect (canonical CSV, gzip), then times the whole pipeline (load, checks, measurement, prediction,
calibration, effect search, before/after errors) and, separately, the report, then ``evaluate`` of
the saved model on every flight (split ``all``: the whole hour). The logs hold PWM and Vbat of a
firmware-like motor (:class:`proxplan.identify.synthetic_logs.SyntheticMotor`), so the thrust-map
measurement runs. Baselines measured in the same run: reading the logs alone, and one evaluation of
the base model over every sample.

    python benchmarks/bench_identify.py [--minutes-per-flight 10] [--flights 6]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

from proxplan.identify import (
    evaluate_model,
    read_log,
    run_identify,
    synthetic_logs,
    write_canonical_csv,
    write_report,
)
from proxplan.identify.synthetic_logs import SyntheticMotor
from proxplan.physics import BUILTIN_VEHICLES, Effect, EffectInputs, SourceSample, base_wrench


def _paths(t: np.ndarray, phase: float) -> dict[str, np.ndarray]:
    a = np.column_stack([0.1 * np.cos(t / 2 + phase), 0.1 * np.sin(t / 2 + phase), 1.6 + 0 * t])
    b = np.column_stack([0.45 * np.sin(1.2 * t + phase), 0.15 * np.sin(0.9 * t), 1.0 - 0.3 * np.sin(t + 3 * phase)])
    return {"a": a, "b": b}


MOTOR = SyntheticMotor(c1_NpV=0.059, c2_NpV2=0.0372, max_thrust_N=0.6)  # small-quad: hover at ~2.4 V, T/W 1.7


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes-per-flight", type=float, default=10.0)
    ap.add_argument("--flights", type=int, default=6)
    ap.add_argument("--data", type=Path, default=None, help="keep/reuse the generated logs in this directory")
    args = ap.parse_args()
    veh = BUILTIN_VEHICLES["small-quad"]
    hidden = Effect("near_field", {"amplitude": 1.5, "decay_L": 3.0})
    with tempfile.TemporaryDirectory() as tmp:
        root = args.data or Path(tmp)
        root.mkdir(parents=True, exist_ok=True)
        t = np.arange(0.0, 60.0 * args.minutes_per_flight, 0.01)
        flights = []
        t0 = time.perf_counter()
        reuse = (root / "manifest.yaml").exists()
        for k in range(0 if reuse else args.flights):
            logs = synthetic_logs(
                {"a": veh, "b": veh},
                _paths(t, 0.7 * k),
                t,
                effects=(hidden,),
                accel_noise_mps2=0.02,
                seed=k,
                motor=MOTOR,
            )
            entry = {"name": f"f{k}", "split": "test" if k >= args.flights - 2 else "train", "vehicles": {}}
            for name, log in logs.items():
                write_canonical_csv(log, root / f"f{k}_{name}.csv.gz")
                entry["vehicles"][name] = {"type": "small-quad", "log": f"f{k}_{name}.csv.gz"}
            flights.append(entry)
        manifest = root / "manifest.yaml"
        if not reuse:
            manifest.write_text(yaml.safe_dump({"format": "canonical", "root": ".", "flights": flights}))
        n_rows = 2 * len(yaml.safe_load(manifest.read_text())["flights"]) * t.size
        hours = n_rows / 2 / 100.0 / 3600.0
        print(
            f"generated {n_rows} rows ({hours:.2f} h of 100 Hz logs x 2 vehicles) in {time.perf_counter() - t0:.1f} s (untimed)"
        )

        t0 = time.perf_counter()
        import pandas  # noqa: F401  (import cost outside the timed read)

        logs = [read_log(p) for p in sorted(root.glob("f*_*.csv.gz"))]
        t_read = time.perf_counter() - t0
        t0 = time.perf_counter()
        for k in range(0, len(logs), 2):
            base_wrench(EffectInputs(veh, logs[k + 1].position_m[:, 2], logs[k + 1].velocity_mps,
                                     (SourceSample(veh, logs[k + 1].position_m - logs[k].position_m),)))  # fmt: skip
        t_base = time.perf_counter() - t0

        t0, c0 = time.perf_counter(), time.process_time()
        result = run_identify(manifest)
        t_pipe, c_pipe = time.perf_counter() - t0, time.process_time() - c0
        t0 = time.perf_counter()
        write_report(result, root / "out")
        t_report = time.perf_counter() - t0
        model = result.saved()
        t0, c0 = time.perf_counter(), time.process_time()
        evaluation = evaluate_model(manifest, model, split="all")
        t_eval, c_eval = time.perf_counter() - t0, time.process_time() - c0

    print(f"baseline: read all logs            {t_read:7.2f} s")
    print(f"baseline: base model on every row  {t_base:7.2f} s")
    print(f"identify pipeline                  {t_pipe:7.2f} s  ({t_pipe / hours:.1f} s per hour of 2-vehicle logs; "
          f"{t_pipe / t_read:.1f}x reading, {t_pipe / t_base:.1f}x one base-model pass)")  # fmt: skip
    print(
        f"identify pipeline CPU time         {c_pipe:7.2f} s  (all threads of this process; the wall time above includes waiting for a shared CPU)"
    )
    print(f"report (markdown + PNG)            {t_report:7.2f} s")
    print(f"selected {result.selected}; test RMSE F_z {result.before.rmse_fz_N:.4g} -> {result.after.rmse_fz_N:.4g} N")
    print(f"evaluate (split all, {evaluation.overall.n} samples) {t_eval:7.2f} s  ({t_eval / hours:.1f} s per hour; "
          f"{t_eval / t_read:.1f}x reading, {t_eval / t_base:.1f}x one base-model pass)")  # fmt: skip
    print(f"evaluate CPU time                   {c_eval:7.2f} s")
    print(f"target identify < 30 s per hour: {'met' if t_pipe / hours < 30 else 'NOT met'}")
    print(f"target evaluate < 15 s per hour: {'met' if t_eval / hours < 15 else 'NOT met'}")


if __name__ == "__main__":
    main()
