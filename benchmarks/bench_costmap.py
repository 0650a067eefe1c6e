"""Speed of `proxplan costmap` and accuracy of the wrench-table interpolant.

    python benchmarks/bench_costmap.py [--source small-quad] [--target large-quad] [--repeats 3]

Prints, measured in the same run on this machine:
* whole-process wall time of `proxplan costmap` for one pair (subprocess, median of --repeats),
* the in-process build time (vectorised model over the map's offsets),
* the same maps' model evaluations done by a naive per-offset Python loop (one
  disturbance_wrench + authority_usage call per offset), and the speed-up ratio,
* interpolant error of the wrench table against the direct model on random in-table points, for
  every ordered pair of built-in vehicles (% of the table's peak |F_z| / peak |tau|).
"""

from __future__ import annotations

import argparse
import math
import statistics
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

from proxplan.costmaps import build_pair_maps
from proxplan.costmaps.cutoff import DEFAULT_CUTOFF_RESOLUTION, cutoff_dz_grid_m
from proxplan.costmaps.wrench_table import DEFAULT_RESOLUTION, LateralScale, build_wrench_table, table_dz_grid_m
from proxplan.physics import (
    BUILTIN_VEHICLES,
    authority_usage,
    disturbance_wrench,
)

ROOT = Path(__file__).resolve().parents[1]


def map_offsets(source, target) -> np.ndarray:
    """Every offset (N, 3) the default maps evaluate: cutoff (r, azimuth, dz) grid + table quadrant."""
    res = DEFAULT_CUTOFF_RESOLUTION
    dz = np.maximum(cutoff_dz_grid_m(source, res), 1e-6 * source.size_m)
    scale = LateralScale.for_pair(source, target, res.lateral_widths)
    rr = np.linspace(0.0, 1.0, res.n_r)[:, None, None] * scale.half_width_m(dz)[None, :, None]
    phi = np.linspace(0.0, 0.25 * math.pi, res.n_azimuth)
    cut = np.stack(np.broadcast_arrays(rr * np.cos(phi), rr * np.sin(phi), -dz[None, :, None]), -1).reshape(-1, 3)
    tres = DEFAULT_RESOLUTION
    tdz = table_dz_grid_m(source, tres)
    tscale = LateralScale.for_pair(source, target, tres.lateral_widths)
    quad = np.linspace(0.0, 1.0, tres.n_xy // 2 + 1)
    qx, qy, qz = np.meshgrid(quad, quad, tdz, indexing="ij")
    w = tscale.half_width_m(qz)
    tab = np.column_stack([(qx * w).ravel(), (qy * w).ravel(), -qz.ravel()])
    return np.vstack([cut, tab])


def naive_loop_s(source, target, offsets: np.ndarray) -> tuple[float, np.ndarray]:
    t0 = time.perf_counter()
    usage = np.empty(len(offsets))
    for i, off in enumerate(offsets):
        batch = disturbance_wrench(source, target, off[None, :])
        usage[i] = authority_usage(target, batch.force_N, batch.torque_Nm)[0]
    return time.perf_counter() - t0, usage


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--source", default="small-quad")
    ap.add_argument("--target", default="large-quad")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument(
        "--naive-fraction",
        type=float,
        default=1.0,
        help="run the naive loop on this fraction of the offsets and scale up (1 = all)",
    )
    args = ap.parse_args()
    source, target = BUILTIN_VEHICLES[args.source], BUILTIN_VEHICLES[args.target]

    with tempfile.TemporaryDirectory() as tmp:
        walls = []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            subprocess.run(
                ["proxplan", "costmap", "--source", args.source, "--target", args.target,
                 "--out", str(Path(tmp) / "m.npz")], check=True, capture_output=True)  # fmt: skip
            walls.append(time.perf_counter() - t0)
    wall = statistics.median(walls)

    t0 = time.perf_counter()
    build_pair_maps(source, target)
    build_s = time.perf_counter() - t0

    offsets = map_offsets(source, target)
    t0 = time.perf_counter()
    batch = disturbance_wrench(source, target, offsets)
    vec_usage = authority_usage(target, batch.force_N, batch.torque_Nm)
    vec_s = time.perf_counter() - t0
    n_naive = max(1, int(round(args.naive_fraction * len(offsets))))
    pick = np.linspace(0, len(offsets) - 1, n_naive).astype(int)
    loop_s, loop_usage = naive_loop_s(source, target, offsets[pick])
    loop_full_s = loop_s * len(offsets) / n_naive
    assert np.allclose(loop_usage, vec_usage[pick], rtol=1e-9, atol=1e-12), "naive loop disagrees"

    print(f"pair {args.source} -> {args.target}: {len(offsets)} model offsets per map")
    print(
        f"  proxplan costmap, whole process (median of {args.repeats}): {wall:6.2f} s  (runs: "
        + ", ".join(f"{w:.2f}" for w in walls)
        + ")"
    )
    print(f"  in-process build (cutoff + table + metadata):        {build_s:6.2f} s")
    print(f"  vectorised model over the map's offsets:              {vec_s:6.2f} s")
    scaled = "" if n_naive == len(offsets) else f" (measured on {n_naive} offsets, scaled)"
    print(f"  naive per-offset Python loop, same offsets:           {loop_full_s:6.2f} s{scaled}")
    print(f"  ratio naive loop / vectorised model:                  {loop_full_s / vec_s:6.1f} x")
    print(f"  ratio naive loop / whole `proxplan costmap` process:  {loop_full_s / wall:6.1f} x")

    print("\ninterpolant error on 20000 random in-table points (max abs error / table peak):")
    rng = np.random.default_rng(0)
    for s_name, s in BUILTIN_VEHICLES.items():
        for t_name, t in BUILTIN_VEHICLES.items():
            table = build_wrench_table(s, t)
            dz = rng.uniform(table.dz_m[0], table.dz_m[-1], 20000)
            half = table.scale.half_width_m(dz)
            xi = rng.uniform(-1.0, 1.0, (20000, 2))
            off = np.column_stack([xi[:, 0] * half, xi[:, 1] * half, -dz])
            direct = disturbance_wrench(s, t, off)
            f, tq = table.wrench_numpy(off)
            ef = np.abs(f[:, 2] - direct.force_N[:, 2]).max() / table.peak_abs_force_N
            peak_t = max(np.abs(table.torque_x_Nm).max(), np.abs(table.torque_y_Nm).max())
            et = np.abs(tq[:, :2] - direct.torque_Nm[:, :2]).max() / peak_t
            print(
                f"  {s_name:>16} -> {t_name:<16} F_z {100 * ef:5.2f} %   torque {100 * et:5.2f} %"
                f"   (peak |F_z| {table.peak_abs_force_N:.3f} N)"
            )


if __name__ == "__main__":
    main()
