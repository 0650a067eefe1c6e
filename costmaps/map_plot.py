"""PNG of a pair's cost maps: cutoff curves r_cut(dz) and the authority-usage heat map in (r, dz).

Axes: dz (m, positive = target below the source) runs downwards on the vertical axis, as in the
flight; horizontal separation r (m) on the horizontal axis. The invalid zone of the field model
(0 < dz <= 3 L_source, S0 II-A) is shaded and its boundary drawn in both panels.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from proxplan.costmaps.cutoff import CutoffMap
from proxplan.fileio import save_figure


def plot_cutoff(cutoff: CutoffMap, path: str | Path, *, title: str | None = None) -> Path:
    """Write the two-panel PNG to ``path`` atomically; returns the path."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.colors import LogNorm

    path = Path(path)
    fig, (ax_cut, ax_map) = plt.subplots(1, 2, figsize=(12, 5.2), sharey=True, constrained_layout=True)
    dz = cutoff.dz_m
    dz_fine = np.linspace(0.0, dz[-1], 400)
    r_grid_top = float(np.max(cutoff.r_grid_m[-1]))
    widest = max(float(cutoff.r_cut_m(dz_fine, level=float(min(cutoff.levels))).max()), cutoff.overlap_radius_m)
    r_top = min(r_grid_top, 1.3 * widest)  # zoom on the informative part of the map
    for level in cutoff.levels:
        style = "-" if np.isclose(level, cutoff.default_level) else "--"
        ax_cut.plot(cutoff.r_cut_m(dz_fine, level=level), dz_fine, style, label=f"usage {level:g}")
    ax_cut.plot(
        cutoff.r_cut_m(dz_fine, level=cutoff.default_level, invalid_rule="model"),
        dz_fine,
        ":",
        color="grey",
        label=f"usage {cutoff.default_level:g}, model numbers in invalid zone",
    )
    for ax in (ax_cut, ax_map):
        ax.axhspan(0.0, cutoff.validity_dz_m, color="tab:red", alpha=0.12, lw=0)
        ax.axhline(cutoff.validity_dz_m, color="tab:red", lw=1.0)
        ax.set_xlabel("horizontal separation r (m)")
    ax_cut.text(
        0.98 * r_top, cutoff.validity_dz_m, f"model valid below (dz > 3 L = {cutoff.validity_dz_m:.2f} m)",
        ha="right", va="bottom", fontsize=8, color="tab:red",
    )  # fmt: skip
    ax_cut.set_ylabel("vertical separation dz (m), target below source")
    ax_cut.set_title(f"cutoff r_cut(dz), invalid zone rule: {cutoff.invalid_rule}")
    ax_cut.legend(fontsize=8, loc="lower right")
    ax_cut.set_xlim(0.0, r_top)
    ax_cut.set_ylim(dz[-1], 0.0)

    usage = np.clip(cutoff.usage, 1e-4, None)
    dz_grid = np.broadcast_to(dz[None, :], cutoff.r_grid_m.shape)
    mesh = ax_map.pcolormesh(
        cutoff.r_grid_m, dz_grid, usage, shading="gouraud", norm=LogNorm(vmin=1e-3, vmax=max(1.0, usage.max()))
    )
    ax_map.contour(cutoff.r_grid_m, dz_grid, cutoff.usage, levels=list(cutoff.levels), colors="white", linewidths=0.7)
    ax_map.set_facecolor(mesh.cmap(0.0))  # beyond the grid the usage is below 1e-3 (see wrench_table)
    ax_map.set_xlim(0.0, r_top)
    fig.colorbar(mesh, ax=ax_map, label="authority usage (max over azimuth), -")
    ax_map.set_title("authority usage in (r, dz); white: stored levels")
    fig.suptitle(title or f"{cutoff.source_name} (source, above) -> {cutoff.target_name} (target, below)")
    return save_figure(fig, path, dpi=90)
