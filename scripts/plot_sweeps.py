"""Reproduce the seed's horizontal sweeps (S0 Fig. 7/8 layout): small quad hovering above the
large quad, target moving along y at dz in {0.5 .. 2.5} m; force z and roll torque, drag and
thrust-change parts, for both forms of (S0-1).

Run:  python scripts/plot_sweeps.py --out docs/figures/sweeps.png
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from proxplan.physics import ModelOptions, disturbance_wrench
from proxplan.physics.builtin_vehicles import LARGE_QUAD, SMALL_QUAD


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="docs/figures/sweeps.png", help="PNG path")
    args = parser.parse_args()
    y = np.linspace(-1.0, 1.0, 401)
    fig, axes = plt.subplots(3, 2, figsize=(11, 10), sharex=True)
    for dz in (0.5, 1.0, 1.5, 2.0, 2.5):
        offsets = np.column_stack([0 * y, y, np.full_like(y, -dz)])
        w = disturbance_wrench(SMALL_QUAD, LARGE_QUAD, offsets)
        p = disturbance_wrench(SMALL_QUAD, LARGE_QUAD, offsets, ModelOptions(field_form="printed"))
        axes[0, 0].plot(y, w.drag_force_N[:, 2], label=f"dz={dz} m")
        axes[0, 1].plot(y, w.drag_torque_Nm[:, 0])
        axes[1, 0].plot(y, w.thrust_force_N[:, 2])
        axes[1, 1].plot(y, w.thrust_torque_Nm[:, 0])
        line = axes[2, 0].plot(y, w.force_N[:, 2])[0]
        axes[2, 0].plot(y, p.force_N[:, 2], ls=":", color=line.get_color())
        axes[2, 1].plot(y, w.torque_Nm[:, 0])
    titles = [
        ("drag force z [N]", "drag roll torque [N m]"),
        ("thrust-change force z [N]", "thrust-change roll torque [N m]"),
        ("total force z [N] (dotted: printed S0-1)", "total roll torque [N m]"),
    ]
    for row, pair in zip(axes, titles):
        for ax, title in zip(row, pair):
            ax.set_title(title)
            ax.grid(alpha=0.3)
    for ax in axes[-1]:
        ax.set_xlabel("target y [m]")
    axes[0, 0].legend()
    fig.suptitle("large-quad below hovering small-quad (S0 IV-F sweeps), 1/z form of (S0-1)")
    fig.tight_layout()
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=90)
    print(args.out)


if __name__ == "__main__":
    main()
