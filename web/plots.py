"""Force, torque and authority-usage plots over time for one vehicle, with a current-time marker.

The figure is rendered once with matplotlib (Agg) to an RGB array; moving the time marker only
paints a one-pixel-wide column into a copy of that array, so playing the plan costs no re-render.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from proxplan.web.wrench_series import WrenchSeries

MARKER_RGB = (220, 0, 0)


@dataclass(frozen=True)
class PlotImage:
    """A rendered figure ``rgb`` (H, W, 3) uint8 whose x axes span ``t_range_s`` over pixel
    columns ``x_px_range`` (left, right) and rows ``y_px_range`` (top, bottom) of the plot area."""

    rgb: np.ndarray
    t_range_s: tuple[float, float]
    x_px_range: tuple[int, int]
    y_px_range: tuple[int, int]

    def column_of(self, t_s: float) -> int:
        """Pixel column of time ``t_s`` (clamped to the axes)."""
        (t0, t1), (x0, x1) = self.t_range_s, self.x_px_range
        frac = 0.0 if t1 <= t0 else float(np.clip((t_s - t0) / (t1 - t0), 0.0, 1.0))
        return int(round(x0 + frac * (x1 - x0)))

    def with_marker(self, t_s: float) -> np.ndarray:
        """Copy of the image with a vertical marker at ``t_s`` through every axes, (H, W, 3) uint8."""
        img = self.rgb.copy()
        col = self.column_of(t_s)
        y0, y1 = self.y_px_range
        img[y0:y1, max(col - 1, 0) : col + 1] = MARKER_RGB
        return img


def render_series(
    series: WrenchSeries, *, name: str, limit: float, width_px: int = 420, height_px: int = 420
) -> PlotImage:
    """Three stacked axes: force (N), torque (N m) and authority usage (-) against time (s)."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    dpi = 100
    fig = Figure(figsize=(width_px / dpi, height_px / dpi), dpi=dpi)
    axes = fig.subplots(3, 1, sharex=True)
    t = series.t_s
    for k, lab in enumerate(("F_x", "F_y", "F_z")):
        axes[0].plot(t, series.force_N[:, k], label=lab, lw=1)
    axes[0].set_ylabel("force [N]", fontsize=8)
    for k, lab in enumerate(("τ_x", "τ_y", "τ_z")):
        axes[1].plot(t, series.torque_Nm[:, k], label=lab, lw=1)
    axes[1].set_ylabel("torque [N m]", fontsize=8)
    axes[2].plot(t, series.usage, color="k", lw=1.2, label="usage")
    axes[2].axhline(limit, color="m", ls="--", lw=1, label=f"limit {limit:.2f}")
    axes[2].set_ylabel("authority usage [-]", fontsize=8)
    y_top = max(1.1 * limit, 1.1 * float(np.max(series.usage, initial=0.0)), 1e-3)
    if series.invalid_zone is not None and np.any(series.invalid_zone):
        axes[2].fill_between(
            t, 0.0, y_top, where=series.invalid_zone, color="0.6", alpha=0.35, lw=0, label="dz <= 3 L (model not valid)"
        )
    axes[2].set_ylim(0.0, y_top)
    axes[2].set_xlabel("time [s]", fontsize=8)
    axes[0].set_title(f"predicted disturbance on {name}", fontsize=9)
    for ax in axes:
        ax.legend(fontsize=6, loc="upper right", ncol=3)
        ax.tick_params(labelsize=7)
        ax.set_xlim(float(t[0]), float(t[-1]) if t[-1] > t[0] else float(t[0]) + 1.0)
        ax.grid(alpha=0.3)
    fig.tight_layout()
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    rgb = np.asarray(canvas.buffer_rgba())[..., :3].copy()
    h = rgb.shape[0]
    top_bbox = axes[0].get_window_extent()
    bottom_bbox = axes[2].get_window_extent()
    x_px = (int(round(top_bbox.x0)), int(round(top_bbox.x1)))
    y_px = (int(round(h - top_bbox.y1)), int(round(h - bottom_bbox.y0)))
    t_end = float(t[-1]) if t[-1] > t[0] else float(t[0]) + 1.0
    return PlotImage(rgb, (float(t[0]), t_end), x_px, y_px)


def render_usage_legend(limit: float, *, width_px: int = 420, height_px: int = 80) -> np.ndarray:
    """Colour bar of the trajectory colours: authority usage 0 .. ``limit``, and above it, (H, W, 3)."""
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize
    from matplotlib.figure import Figure

    from proxplan.web.scene import OVER_LIMIT_RGB, USAGE_COLORMAP

    fig = Figure(figsize=(width_px / 100, height_px / 100), dpi=100)
    ax = fig.add_axes((0.05, 0.4, 0.72, 0.25))
    fig.colorbar(ScalarMappable(Normalize(0.0, limit), USAGE_COLORMAP), cax=ax, orientation="horizontal")
    ax.tick_params(labelsize=7)
    fig.text(0.05, 0.8, "trajectory colour: authority usage [-] (limit at the right end)", fontsize=8)
    over = fig.add_axes((0.82, 0.4, 0.14, 0.25))
    r, g, b = (float(c) / 255 for c in OVER_LIMIT_RGB)
    over.set_facecolor((r, g, b))
    over.set_xticks([])
    over.set_yticks([])
    over.set_xlabel(f"> {limit:.2f}", fontsize=7)
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3].copy()
