"""Predicted disturbance on each vehicle along a plan: force, torque and authority usage over time.

For each target vehicle, every other vehicle is a hovering downwash source (S0 section II) at its
planned position; the wrenches of all sources are summed (world frame, N and N m) and the target's
authority usage (DESIGN.md section 3) is evaluated on the sum. Uses
``planner.verify.wrench_along_plan`` when the planner provides it, otherwise the same model
directly (``costmaps.disturbance.disturbance_wrench`` + ``costmaps.authority.authority_usage``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from web.review_data import ReviewData


@dataclass(frozen=True)
class WrenchSeries:
    """One target's predicted disturbance on the grid ``t_s`` (N,), s.

    ``force_N`` (N, 3), N and ``torque_Nm`` (N, 3), N m about its centre of mass, world frame;
    ``usage`` (N,) authority usage, - (0 untouched, 1 a motor saturates).
    """

    t_s: np.ndarray
    force_N: np.ndarray
    torque_Nm: np.ndarray
    usage: np.ndarray


def _from_planner(data: ReviewData, t_s: np.ndarray) -> dict[str, WrenchSeries] | None:
    if data.plan is None or data.scenario is None:
        return None
    try:
        from planner.verify import wrench_along_plan
    except ImportError:
        return None
    try:
        result = wrench_along_plan(data.plan, data.scenario, t_s=t_s)
    except Exception as err:  # noqa: BLE001 - fall back to the model, but say so
        import sys

        print(f"proxplan view: planner.verify.wrench_along_plan failed ({type(err).__name__}: {err}); "
              "using costmaps directly", file=sys.stderr)
        return None
    series = {}
    for name in data.vehicles:
        item = result[name]
        get = (lambda k: item[k]) if isinstance(item, dict) else (lambda k: getattr(item, k))
        series[name] = WrenchSeries(t_s, np.asarray(get("force_N")), np.asarray(get("torque_Nm")),
                                    np.asarray(get("usage")))
    return series


def _from_model(data: ReviewData, t_s: np.ndarray) -> dict[str, WrenchSeries]:
    from costmaps.authority import authority_usage
    from costmaps.disturbance import disturbance_wrench

    pos = {name: np.stack([v.position_at(t) for t in t_s]) for name, v in data.vehicles.items()}
    series = {}
    for tgt_name, tgt in data.vehicles.items():
        force = np.zeros((t_s.size, 3))
        torque = np.zeros((t_s.size, 3))
        for src_name, src in data.vehicles.items():
            if src_name == tgt_name:
                continue
            batch = disturbance_wrench(src.vehicle, tgt.vehicle, pos[tgt_name] - pos[src_name])
            force += batch.force_N
            torque += batch.torque_Nm
        usage = authority_usage(tgt.vehicle, force, torque)
        series[tgt_name] = WrenchSeries(t_s, force, torque, usage)
    return series


def wrench_series(data: ReviewData, *, max_samples: int = 600) -> dict[str, WrenchSeries]:
    """Predicted wrench and usage of every vehicle on a common grid of at most ``max_samples``."""
    n = int(min(max_samples, max(len(v.t_s) for v in data.vehicles.values())))
    t_s = np.linspace(data.t_start_s, data.t_end_s, max(n, 2))
    return _from_planner(data, t_s) or _from_model(data, t_s)
