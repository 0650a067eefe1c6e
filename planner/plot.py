"""PNG of a plan: top view (x-y), side view (x-z) of every trajectory and authority usage over time."""

from __future__ import annotations

from pathlib import Path

from proxplan.fileio import save_figure
from proxplan.planfile import Plan


def plot_plan(plan: Plan, scenario, path: str | Path, *, usage: dict | None = None) -> Path:
    """Write the figure to ``path`` (written to a temporary name, then renamed); returns the path.

    ``usage``: {vehicle: WrenchAlongPlan} on ``plan.t_s`` (computed when None).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    from proxplan.verify import wrench_along_plan

    if usage is None:
        usage = wrench_along_plan(plan, scenario, t_s=plan.t_s)
    fig, axes = plt.subplots(1, 3, figsize=(16, 5.2))
    top, side, ax_u = axes
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    lo, hi = scenario.workspace_min_m, scenario.workspace_max_m
    for ax, (i, j), title in ((top, (0, 1), "top view"), (side, (0, 2), "side view")):
        ax.add_patch(Rectangle((lo[i], lo[j]), hi[i] - lo[i], hi[j] - lo[j], fill=False, ls="--", color="grey"))
        for box in scenario.obstacles:
            ax.add_patch(
                Rectangle(
                    (box.min_m[i], box.min_m[j]),
                    box.max_m[i] - box.min_m[i],
                    box.max_m[j] - box.min_m[j],
                    color="0.6",
                    alpha=0.6,
                )
            )
        for k, (name, tr) in enumerate(plan.vehicles.items()):
            c = colors[k % len(colors)]
            ax.plot(tr.position_m[:, i], tr.position_m[:, j], color=c, lw=1.6, label=name)
            ax.plot(tr.position_m[0, i], tr.position_m[0, j], "o", color=c, ms=5)
            ax.plot(tr.position_m[-1, i], tr.position_m[-1, j], "s", color=c, ms=6, mfc="none")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]" if j == 1 else "z [m]")
        ax.set_title(title + " (o start, square end)")
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(alpha=0.3)
    top.legend(fontsize=8, loc="best")
    for k, name in enumerate(plan.vehicles):
        ax_u.plot(plan.t_s, usage[name].usage, color=colors[k % len(colors)], label=name)
    ax_u.axhline(scenario.limits.authority_fraction, color="r", ls="--", label="authority_fraction")
    ax_u.set_xlabel("t [s]")
    ax_u.set_ylabel("authority usage [-]")
    ax_u.set_title("authority usage (model, all sources)")
    ax_u.grid(alpha=0.3)
    ax_u.legend(fontsize=8)
    fig.suptitle(f"{plan.scenario}: {plan.method}, makespan {plan.metrics.get('makespan_s', float('nan')):.2f} s")
    fig.subplots_adjust(left=0.05, right=0.98, bottom=0.1, top=0.87, wspace=0.25)
    return save_figure(fig, path, dpi=80)
