"""PNG of a plan: top view (x-y), side view (x-z) of every trajectory and authority usage over time.

Every panel draws all vehicles in one collection (``matplotlib.collections.LineCollection``, one
scatter for the starts and one for the ends), so a 256-vehicle plan costs about what a 4-vehicle one
does. Up to :data:`NAMED_VEHICLES` vehicles each get a colour and a legend entry; a larger swarm is
drawn in thin lines, and the usage panel names only the :data:`NAMED_VEHICLES` with the highest
authority usage (the others thin and grey).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from proxplan.fileio import save_figure
from proxplan.planfile import Plan

NAMED_VEHICLES = 8
"""Largest number of vehicles named in the legends, -."""


def _usage_series(plan: Plan, scenario, usage: dict | None) -> dict[str, np.ndarray]:
    """Authority usage (M,) per vehicle on ``plan.t_s``: from ``usage`` ({vehicle: WrenchAlongPlan}),
    else from the plan's own predicted wrench (its feed-forward, written by ``finish_metrics``),
    else evaluated (``proxplan.verify.wrench_along_plan``)."""
    from proxplan.physics import authority_usage

    if usage is not None:
        return {n: np.asarray(usage[n].usage) for n in plan.vehicles}
    out = {}
    for n, tr in plan.vehicles.items():
        force, torque = tr.disturbance_force_N, tr.disturbance_torque_Nm
        if force is None or torque is None:
            break
        out[n] = authority_usage(scenario.vehicles[n].vehicle, force, torque)
    else:
        return out
    from proxplan.verify import wrench_along_plan

    return {n: w.usage for n, w in wrench_along_plan(plan, scenario, t_s=plan.t_s).items()}


def plot_plan(plan: Plan, scenario, path: str | Path, *, usage: dict | None = None) -> Path:
    """Write the figure to ``path`` (written to a temporary name, then renamed); returns the path.

    ``usage``: {vehicle: WrenchAlongPlan} on ``plan.t_s`` (when None: the plan's feed-forward
    wrench, or computed).
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection
    from matplotlib.lines import Line2D
    from matplotlib.patches import Rectangle

    names = list(plan.vehicles)
    few = len(names) <= NAMED_VEHICLES
    series = _usage_series(plan, scenario, usage)
    fig, axes = plt.subplots(1, 3, figsize=(16, 5.2))
    top, side, ax_u = axes
    cycle = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    colors = (
        [cycle[k % len(cycle)] for k in range(len(names))] if few else plt.cm.viridis(np.linspace(0, 1, len(names)))
    )
    lw = 1.6 if few else max(0.3, 1.2 / np.sqrt(len(names) / NAMED_VEHICLES))
    pos = [plan.vehicles[n].position_m for n in names]
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
        ax.add_collection(LineCollection([p[:, [i, j]] for p in pos], colors=colors, linewidths=lw))
        starts = np.array([p[0, [i, j]] for p in pos])
        ends = np.array([p[-1, [i, j]] for p in pos])
        ax.scatter(starts[:, 0], starts[:, 1], marker="o", s=25 if few else 6, color=colors, zorder=3)
        ax.scatter(
            ends[:, 0], ends[:, 1], marker="s", s=36 if few else 8, facecolors="none", edgecolors=colors, zorder=3
        )
        ax.autoscale_view()
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]" if j == 1 else "z [m]")
        ax.set_title(title + " (o start, square end)")
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(alpha=0.3)
    if few:
        top.legend([Line2D([], [], color=c, lw=lw) for c in colors], names, fontsize=8, loc="best")
    else:
        top.text(0.01, 0.99, f"{len(names)} vehicles", transform=top.transAxes, va="top", fontsize=8)
    worst = sorted(names, key=lambda n: -float(np.max(series[n], initial=0.0)))[:NAMED_VEHICLES]
    named = names if few else worst
    if not few:
        grey = [np.column_stack([plan.t_s, series[n]]) for n in names if n not in worst]
        ax_u.add_collection(LineCollection(grey, colors="0.7", linewidths=0.4))
    named_colors = (
        [colors[names.index(n)] for n in named] if few else [cycle[k % len(cycle)] for k in range(len(named))]
    )
    ax_u.add_collection(
        LineCollection([np.column_stack([plan.t_s, series[n]]) for n in named], colors=named_colors, linewidths=1.4)
    )
    ax_u.autoscale_view()
    handles = [Line2D([], [], color=c, lw=1.4) for c in named_colors]
    labels = list(named) if few else [f"{n} (max {float(np.max(series[n], initial=0.0)):.3f})" for n in named]
    if not few:
        handles.append(Line2D([], [], color="0.7", lw=0.6))
        labels.append(f"{len(names) - len(named)} others")
    limit = ax_u.axhline(scenario.limits.authority_fraction, color="r", ls="--")
    ax_u.legend([*handles, limit], [*labels, "authority_fraction"], fontsize=8)
    ax_u.set_xlabel("t [s]")
    ax_u.set_ylabel("authority usage [-]")
    ax_u.set_title("authority usage (model, all sources)" + ("" if few else f": the {len(named)} highest named"))
    ax_u.grid(alpha=0.3)
    fig.suptitle(f"{plan.scenario}: {plan.method}, makespan {plan.metrics.get('makespan_s', float('nan')):.2f} s")
    fig.subplots_adjust(left=0.05, right=0.98, bottom=0.1, top=0.87, wspace=0.25)
    return save_figure(fig, path, dpi=80)
