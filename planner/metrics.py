"""A plan's metrics (DESIGN.md section 4 and extras) and the predicted deflections that grow the
planners' tubes. World frame, m, s.

* :func:`finish_metrics`: ``planning_time_s``, ``max_authority_usage``, ``min_separation_m``,
  ``makespan_s`` (the time the last vehicle stops moving) and the per-vehicle extras, from the
  model evaluated along the plan (:func:`proxplan.verify.wrench_along_plan`), plus the predicted
  wrench as feed-forward.
* :func:`deflection_allowance`: per vehicle the largest predicted growth of its tube, flying its own
  reference and under the plan's own disturbance (:func:`proxplan.verify.deflection_along_plan`). This is the one deflection policy of
  the planners: a vehicle's tube grows by its own value, so a pair's keep-out grows by the sum of
  its two vehicles' values, as in the verifier.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from proxplan.planfile import Plan, Scenario
from proxplan.planner.ties import rounded_up
from proxplan.planner.timing.plan_grid import moving_end_s

DEFLECTION_DT_S = 0.01  # time step at which the deflections are evaluated along the plan, s (the verifier's default)
# Each allowance is rounded UP to a multiple of this, m (round 37W, issue 37: "the same seed gives the same plan on any
# machine"). The deflections are the loop's response to the predicted wrench along the plan, made through numpy,
# whose SIMD kernels are picked at run time, so their last bits differ between kernels (AVX-512 vs AVX2, round 37V).
# After a failed verify they grow the re-plan's keep-outs (pipeline._until_verified -> SwarmOptions.deflection_m,
# sampling options' deflection_m) and the exact comparison of _no_narrower: unrounded, two machines can re-plan
# differently. Derivation, as for the tracking bound (swarm.tracking_bound.TRACKING_BOUND_RESOLUTION_M). Below: the
# float error of a deflection, a loop response over the plan's samples on DEFLECTION_DT_S (a 60 s plan: 6000
# samples): relative error <~ 6000 x 1.1e-16 ~ 7e-13, so <~ 1e-14 m on a cm-scale deflection; 1e-9 m is ~1e5 times
# that. Above: what a plan resolves: the verifier's separation tolerance 1e-6 m (verify/pair_checks.py) and the swarm
# layer's millimetre grid (problem.GROWTH_M); rounding up grows a tube by < 1e-9 m, 1e3 and 1e6 below them.
# Conservative: an allowance only grows. Set before any figure was measured (= planner.ties.LENGTH_RESOLUTION_M).
DEFLECTION_RESOLUTION_M = 1e-9

__all__ = ["DEFLECTION_RESOLUTION_M", "deflection_allowance", "finish_metrics"]


def deflection_allowance(
    plan: Plan, scenario: Scenario, *, deflections: Mapping[str, np.ndarray] | None = None
) -> dict[str, float]:
    """Per vehicle the largest distance, m, its controller is predicted to be pushed off the plan by
    the plan's own predicted disturbance, for vehicles pushed at all (see module). ``deflections``: the
    per-vehicle deflections (M,) m the verifier already predicted on the grid of step
    :data:`DEFLECTION_DT_S` (:func:`proxplan.verify.verify_with_deflections`); None: predicted here. Each value is
    rounded up to :data:`DEFLECTION_RESOLUTION_M` (round 37W: one float on every machine's numpy kernels)."""
    if deflections is None:
        from proxplan.verify import deflection_along_plan, wrench_along_plan

        t = np.arange(0.0, float(plan.t_s[-1]) + 0.5 * DEFLECTION_DT_S, DEFLECTION_DT_S)
        deflections = deflection_along_plan(plan, scenario, wrench_along_plan(plan, scenario, t_s=t))
    return {
        n: rounded_up(float(d.max()), DEFLECTION_RESOLUTION_M)
        for n, d in deflections.items()
        if d.size and d.max() > 0.0
    }


def finish_metrics(scenario: Scenario, plan: Plan, *, planning_time_s: float) -> None:
    """Fill the DESIGN metrics (planning_time_s, max_authority_usage, min_separation_m, makespan_s)
    and extras (per-vehicle usage, path length, invalid-zone time of docks)."""
    from proxplan.verify import attach_feedforward, separation_summary, wrench_along_plan

    along = wrench_along_plan(plan, scenario, t_s=plan.t_s)
    attach_feedforward(plan, along)  # the predicted wrench, for controllers that feed it forward
    usage = {n: max(0.0, float(a.usage.max())) for n, a in along.items()}
    sep = separation_summary(plan, scenario)
    plan.metrics.update(
        {
            "planning_time_s": round(float(planning_time_s), 4),
            "max_authority_usage": max(usage.values()) if usage else 0.0,
            "min_separation_m": sep["min_separation_m"],
            "makespan_s": moving_end_s(plan),
            "authority_fraction": scenario.limits.authority_fraction,
            "tracking_margin_m": scenario.limits.tracking_margin_m,
            "authority_usage_by_vehicle": usage,
            "invalid_zone_s_by_vehicle": {n: float(a.invalid_zone.sum() * plan.dt_s) for n, a in along.items()},
            "min_dock_separation_m": sep["min_dock_separation_m"],
            "path_length_m": {
                n: float(np.linalg.norm(np.diff(tr.position_m, axis=0), axis=1).sum())
                for n, tr in plan.vehicles.items()
            },
        }
    )
