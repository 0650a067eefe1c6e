"""What a plan promises about each vehicle's flight, as simulate and certify check it: the tube the
verifier grants plus its growth (its tracking error along its own reference and in the jets,
:mod:`proxplan.verify.jet_loop`), on the verifier's
grid, from the plan file alone (its embedded scenario)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from proxplan.planfile import Plan
from proxplan.verify.along import wrench_along_plan
from proxplan.verify.checks import scenario_of_plan
from proxplan.verify.jet_loop import loop_along_plan


@dataclass(frozen=True)
class TubeGrowth:
    """How far each vehicle of a plan is predicted to leave its plan beyond its tracking tube: on
    the uniform grid ``t_s`` (M,), s, from the plan's start, ``growth_m`` {vehicle: (M,)} m
    (:func:`loop_along_plan`; the hold after the end in the last sample), ``tube_m`` the tube the
    verifier grants (``limits.tracking_margin_m``; None: no scenario, each type's own tube),
    ``undamped`` the vehicles whose loop is not damped where they hold at the end (no bound after it)."""

    t_s: np.ndarray
    growth_m: dict[str, np.ndarray]
    tube_m: float | None
    undamped: tuple[str, ...] = ()

    def at(self, name: str, t_s: np.ndarray) -> np.ndarray:
        """``name``'s growth (K,), m, at plan times ``t_s`` (K,), s (the last value after the end;
        inf there for an undamped vehicle)."""
        g = self.growth_m.get(name)
        t = np.asarray(t_s, dtype=float)
        if g is None or self.t_s.size == 0:
            return np.zeros(t.size)
        out = np.interp(t, self.t_s, g)
        if name in self.undamped:
            out[t > self.t_s[-1] + 1e-9] = np.inf
        return out


def predicted_tube_growth(plan: Plan, *, dt_s: float = 0.01) -> TubeGrowth:
    """:class:`TubeGrowth` of ``plan`` with the scenario embedded in it (the verifier's numbers,
    evaluated on the verifier's grid of step ``dt_s``, s)."""
    has = getattr(plan, "scenario_spec", None) is not None or getattr(plan, "scenario_file", None)
    scenario = scenario_of_plan(plan) if has else None
    t = np.arange(0.0, float(plan.t_s[-1]) + dt_s / 2, dt_s)
    loops = loop_along_plan(plan, scenario, wrench_along_plan(plan, scenario, t_s=t))
    tube = float(scenario.limits.tracking_margin_m) if scenario is not None else None
    undamped = tuple(n for n, lp in loops.items() if lp.response is not None and lp.response.poles.growth_ps[0] >= 0.0)
    return TubeGrowth(t, {n: lp.deflection_m for n, lp in loops.items()}, tube, undamped)
