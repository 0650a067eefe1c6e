"""Predicted disturbance on each vehicle along a plan: force, torque and authority usage over time.

Thin adapter over ``proxplan.verify.checks.wrench_along_plan`` (every other vehicle above a target is a
hovering downwash source, S0 section II; wrenches summed in the world frame; authority usage of
DESIGN.md section 3 on the sum), resampled on a common grid for plotting and colouring.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from proxplan.web.review_data import ReviewData


@dataclass(frozen=True)
class WrenchSeries:
    """One target's predicted disturbance on the grid ``t_s`` (N,), s.

    ``force_N`` (N, 3), N and ``torque_Nm`` (N, 3), N m about its centre of mass, world frame;
    ``usage`` (N,) authority usage, - (0 untouched, 1 a motor saturates); ``invalid_zone`` (N,) True
    where the target is in a source's zone of unestablished flow (dz <= 3 L, S0 II-A).
    """

    t_s: np.ndarray
    force_N: np.ndarray
    torque_Nm: np.ndarray
    usage: np.ndarray
    invalid_zone: np.ndarray | None = None


def wrench_series(data: ReviewData, *, max_samples: int = 600) -> dict[str, WrenchSeries]:
    """Predicted wrench and usage of every vehicle on a common grid of at most ``max_samples``;
    empty when the plan carries no scenario (vehicle models and limits unknown)."""
    if data.plan is None or data.scenario is None:
        return {}
    from proxplan.verify import wrench_along_plan

    n = int(min(max_samples, max(len(v.t_s) for v in data.vehicles.values())))
    t_s = np.linspace(data.t_start_s, data.t_end_s, max(n, 2))
    result = wrench_along_plan(data.plan, data.scenario, t_s=t_s)
    return {
        name: WrenchSeries(
            t_s,
            np.asarray(w.force_N),
            np.asarray(w.torque_Nm),
            np.asarray(w.usage),
            np.asarray(w.invalid_zone, dtype=bool),
        )
        for name, w in result.items()
    }
