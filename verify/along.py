"""What the model predicts along a plan: disturbance wrench, authority usage, invalid zone, and
separations (the dock pairs' final approach told apart), evaluated with the model directly.

The wrench on each vehicle is the sum over every other vehicle above it of
``proxplan.physics.disturbance.disturbance_wrench`` (S0-3..S0-8) plus the scenario's effects between vehicles
(a calibrated model's, ``Scenario.effects``), through ``proxplan.costmaps.pair_wrench`` (the one
implementation, ``proxplan.physics.effects.total_wrench``; where two or more sources are above at once,
``proxplan.costmaps.sources_wrench`` evaluates them together: an upper jet is shielded by the sources
between (``proxplan.physics.stack``) and an effect of several sources need not add up); its authority usage comes from
``proxplan.physics.authority.authority_usage`` (DESIGN.md s. 3). Positions between plan samples come from
the plan-file sampler. World frame, z up; m, N, N m, s.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from proxplan.costmaps import pair_wrench, sources_wrench
from proxplan.physics import ModelOptions, authority_usage, disturbance_deflection, invalid_zone_mask
from proxplan.planfile import Plan, Scenario

DOCK_TUBE_M = 0.1  # radius of the dock-approach tube where a dock pair is exempt, m


def model_options(scenario: Scenario | None) -> ModelOptions:
    """The disturbance-model options a scenario asks for (defaults without a scenario)."""
    return scenario.model_options if scenario is not None else ModelOptions()


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


def wrench_along_plan(plan: Plan, scenario: Scenario | None, *, t_s: np.ndarray) -> dict[str, WrenchAlongPlan]:
    """Per-vehicle disturbance wrench and authority usage at times ``t_s`` (M,), s, summed over
    every other vehicle as a source (those above it), evaluated with the model directly. Without
    a scenario the plan's own vehicle parameters and the default model options are used."""
    t_s = np.asarray(t_s, dtype=float)
    pos = plan.positions_at(t_s)
    opts = model_options(scenario)
    effects = scenario.effects if scenario is not None else plan.effects
    out = {}
    for tname in plan.vehicles:
        target = _vehicle(plan, scenario, tname)
        force = np.zeros((t_s.size, 3))
        torque = np.zeros((t_s.size, 3))
        by_source = {}
        invalid = np.zeros(t_s.size, dtype=bool)
        n_below = np.zeros(t_s.size, dtype=int)
        for sname in plan.vehicles:
            if sname == tname:
                continue
            source = _vehicle(plan, scenario, sname)
            off = pos[tname] - pos[sname]
            below = -off[:, 2] > 1e-6
            u_src = np.zeros(t_s.size)
            if below.any():
                f_src, t_src = pair_wrench(source, target, off[below], opts, effects)
                force[below] += f_src
                torque[below] += t_src
                u_src[below] = authority_usage(target, f_src, t_src)
                inv = invalid_zone_mask(source, target, off[below])
                invalid[np.nonzero(below)[0][inv]] = True
            by_source[sname] = u_src
            n_below += below
        stack = n_below >= 2
        if stack.any():  # several sources at once: shielding (proxplan.physics.stack), effects need not add up
            others = [n for n in plan.vehicles if n != tname]
            offsets = [(_vehicle(plan, scenario, n), (pos[tname] - pos[n])[stack]) for n in others]
            force[stack], torque[stack] = sources_wrench(target, offsets, opts, effects)
        usage = authority_usage(target, force, torque) if t_s.size else np.zeros(0)
        out[tname] = WrenchAlongPlan(t_s, force, torque, usage, by_source, invalid)
    return out


def deflection_along_plan(
    plan: Plan, scenario: Scenario | None, along: dict[str, WrenchAlongPlan]
) -> dict[str, np.ndarray]:
    """Per vehicle the distance (M,), m, its controller is predicted to be pushed off its plan by
    the disturbance the model predicts on it along the plan (``along``, on a uniform grid from the
    plan's start): :func:`proxplan.physics.disturbance_deflection` (steady sag F / k_p, its
    transient, the tilt a torque holds), from rest. Part of that vehicle's tube where it applies."""
    out = {}
    for name, w in along.items():
        d = disturbance_deflection(w.t_s, w.force_N, w.torque_Nm, _vehicle(plan, scenario, name))
        out[name] = np.linalg.norm(d, axis=1)
    return out


def _vehicle(plan: Plan, scenario: Scenario | None, name: str):
    return scenario.vehicles[name].vehicle if scenario is not None else plan.vehicles[name].vehicle


def attach_feedforward(plan: Plan, along: dict[str, WrenchAlongPlan]) -> None:
    """Store the predicted wrench ``along`` (evaluated at ``plan.t_s``) in the plan as every
    vehicle's feed-forward (``disturbance_force_N``, ``disturbance_torque_Nm``), in place."""
    for name, tr in list(plan.vehicles.items()):
        w = along[name]
        if w.t_s.shape != tr.t_s.shape or not np.allclose(w.t_s, tr.t_s):
            raise ValueError("attach_feedforward: the wrench must be evaluated on the plan's time grid")
        plan.vehicles[name] = replace(
            tr, disturbance_force_N=w.force_N.copy(), disturbance_torque_Nm=w.torque_Nm.copy()
        )


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
