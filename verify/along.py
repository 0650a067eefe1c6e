"""What the model predicts along a plan: disturbance wrench, authority usage, invalid zone, and
separations (the dock pairs' final approach told apart), evaluated with the model directly.

The wrench on each vehicle is the sum over every other vehicle above it of
``physics.disturbance.disturbance_wrench`` (S0-3..S0-8) plus the scenario's effects between vehicles
(a calibrated model's, ``Scenario.effects``), through ``costmaps.pair_wrench`` (the one
implementation, ``physics.effects.total_wrench``; where two or more sources are above at once and
there are effects, ``costmaps.sources_wrench`` evaluates them together, so an effect of several
sources need not add up); its authority usage comes from
``physics.authority.authority_usage`` (DESIGN.md s. 3). Positions between plan samples come from
the plan-file sampler. World frame, z up; m, N, N m, s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from costmaps import pair_wrench, sources_wrench
from physics import VALIDITY_FACTOR_L, ModelOptions, authority_usage
from planfile import Plan, Scenario

DOCK_TUBE_M = 0.1  # radius of the dock-approach tube where a dock pair is exempt, m


def model_options(scenario: Scenario) -> ModelOptions:
    """The disturbance-model options a scenario asks for."""
    return ModelOptions(field_form=scenario.field_form) if scenario.field_form else ModelOptions()


@dataclass(frozen=True)
class WrenchAlongPlan:
    """Disturbance on one vehicle along the plan at times ``t_s`` (M,), s.

    ``force_N`` (M, 3) N and ``torque_Nm`` (M, 3) N m, world frame, summed over all sources above;
    ``usage`` (M,) authority usage; ``usage_by_source`` {source: (M,)} usage of each source alone;
    ``invalid_zone`` (M,) True where the vehicle is in a source's invalid zone (0 < dz <= 3 L) with
    overlapping footprints.
    """

    t_s: np.ndarray
    force_N: np.ndarray
    torque_Nm: np.ndarray
    usage: np.ndarray
    usage_by_source: dict
    invalid_zone: np.ndarray


def wrench_along_plan(plan: Plan, scenario: Scenario, *, t_s: np.ndarray) -> dict[str, WrenchAlongPlan]:
    """Per-vehicle disturbance wrench and authority usage at times ``t_s`` (M,), s, summed over
    every other vehicle as a source (those above it), evaluated with the model directly."""
    t_s = np.asarray(t_s, dtype=float)
    pos = plan.positions_at(t_s)
    opts = model_options(scenario)
    out = {}
    for tname in plan.vehicles:
        target = scenario.vehicles[tname].vehicle
        force = np.zeros((t_s.size, 3))
        torque = np.zeros((t_s.size, 3))
        by_source = {}
        invalid = np.zeros(t_s.size, dtype=bool)
        n_below = np.zeros(t_s.size, dtype=int)
        for sname in plan.vehicles:
            if sname == tname:
                continue
            source = scenario.vehicles[sname].vehicle
            off = pos[tname] - pos[sname]
            below = -off[:, 2] > 1e-6
            u_src = np.zeros(t_s.size)
            if below.any():
                f_src, t_src = pair_wrench(source, target, off[below], opts, scenario.effects)
                force[below] += f_src
                torque[below] += t_src
                u_src[below] = authority_usage(target, f_src, t_src)
                r = np.hypot(off[below, 0], off[below, 1])
                inv = (-off[below, 2] <= VALIDITY_FACTOR_L * source.size_m) & (
                    r < source.body_radius_m + target.body_radius_m
                )
                invalid[np.nonzero(below)[0][inv]] = True
            by_source[sname] = u_src
            n_below += below
        stack = n_below >= 2
        if scenario.effects and stack.any():  # several sources at once: effects need not add up
            others = [n for n in plan.vehicles if n != tname]
            offsets = [(scenario.vehicles[n].vehicle, (pos[tname] - pos[n])[stack]) for n in others]
            force[stack], torque[stack] = sources_wrench(target, offsets, opts, scenario.effects)
        usage = authority_usage(target, force, torque) if t_s.size else np.zeros(0)
        out[tname] = WrenchAlongPlan(t_s, force, torque, usage, by_source, invalid)
    return out


def dock_exempt(plan: Plan, scenario: Scenario, a: str, b: str, pos: dict, t_s: np.ndarray) -> np.ndarray:
    """(M,) True where pair (a, b) is a dock pair and the docker is on its final approach: within
    ``DOCK_TUBE_M`` of the segment from the approach point A to the dock point D, both taken
    relative to the dock target's current position."""
    for docker, target in ((a, b), (b, a)):
        task = scenario.vehicles[docker]
        if task.dock_with == target:
            ap, dp = scenario.dock_geometry(docker)
            base = scenario.final_position_m(target)
            a_rel, d_rel = ap - base, dp - base  # relative to the target
            rel = pos[docker] - pos[target]
            seg = a_rel - d_rel
            f = np.clip((rel - d_rel) @ seg / max(float(seg @ seg), 1e-12), 0.0, 1.0)
            dist = np.linalg.norm(rel - (d_rel + f[:, None] * seg), axis=1)
            return dist <= DOCK_TUBE_M
    return np.zeros(t_s.size, dtype=bool)


def separation_summary(plan: Plan, scenario: Scenario, *, t_s: np.ndarray | None = None) -> dict:
    """Smallest centre distance over non-dock pairs (and over docking pairs), m; None if < 2 vehicles."""
    t_s = plan.t_s if t_s is None else t_s
    pos = plan.positions_at(t_s)
    names = list(plan.vehicles)
    best, best_dock = None, None
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            d = np.linalg.norm(pos[a] - pos[b], axis=1)
            ex = dock_exempt(plan, scenario, a, b, pos, t_s)
            if (~ex).any():
                m = float(d[~ex].min())
                best = m if best is None else min(best, m)
            if ex.any():
                m = float(d[ex].min())
                best_dock = m if best_dock is None else min(best_dock, m)
    return {"min_separation_m": best, "min_dock_separation_m": best_dock}
