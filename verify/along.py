"""What the model predicts along a plan: disturbance wrench, authority usage, invalid zone, and
separations (the dock pairs' final approach told apart), evaluated with the model directly.

The wrench on each vehicle is the sum over every other vehicle above it of
``proxplan.physics.disturbance.disturbance_wrench`` (S0-3..S0-8) plus the scenario's effects between vehicles
(a calibrated model's, ``Scenario.effects``), through ``proxplan.costmaps.pair_wrench`` (the one
implementation, ``proxplan.physics.effects.total_wrench``; where two or more sources are above at once,
they are evaluated together as ``proxplan.costmaps.sources_wrench`` does: an upper jet is shielded by the sources
between (``proxplan.physics.stack``) and an effect of several sources need not add up), on the pairs within
reach (:mod:`proxplan.verify.plan_wrench`); its authority usage comes from
``proxplan.physics.authority.authority_usage`` (DESIGN.md s. 3). Positions between plan samples come from
the plan-file sampler. World frame, z up; m, N, N m, s.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass, replace

import numpy as np

from proxplan.physics import ModelOptions, authority_usage
from proxplan.planfile import Plan, Scenario
from proxplan.verify.plan_wrench import PlanWrench
from proxplan.verify.tolerances import REST_SPEED_MPS

DOCK_TUBE_M = 0.1  # radius of the dock-approach tube where a dock pair is exempt, m


def model_options(scenario: Scenario | None) -> ModelOptions:
    """The disturbance-model options a scenario asks for (defaults without a scenario)."""
    return scenario.model_options if scenario is not None else ModelOptions()


@dataclass(frozen=True)
class WrenchAlongPlan:
    """Disturbance on one vehicle along the plan at times ``t_s`` (M,), s.

    ``force_N`` (M, 3) N and ``torque_Nm`` (M, 3) N m, world frame, summed over all sources above;
    ``usage`` (M,) authority usage; ``usage_by_source`` {source: (M,)} usage of each source alone
    (a :class:`UsageBySource`: each array built when asked for);
    ``invalid_zone`` (M,) True where the vehicle is in a source's invalid zone (0 < dz <= 3 L) with
    overlapping footprints.
    """

    t_s: np.ndarray
    force_N: np.ndarray
    torque_Nm: np.ndarray
    usage: np.ndarray
    usage_by_source: Mapping[str, np.ndarray]
    invalid_zone: np.ndarray


class UsageBySource(Mapping):
    """{source: (M,) authority usage of that source alone} of one target, each array built when asked
    for from the samples where the source is in reach (0 on the others): held over those samples only."""

    def __init__(self, m: int, sparse: dict[str, tuple[np.ndarray, np.ndarray]]):
        self._m = int(m)
        self._sparse = sparse  # source -> (sample indices (R,), usage (R,))

    def __getitem__(self, source: str) -> np.ndarray:
        at, usage = self._sparse[source]
        out = np.zeros(self._m)
        out[at] = usage
        return out

    def __iter__(self) -> Iterator[str]:
        return iter(self._sparse)

    def __len__(self) -> int:
        return len(self._sparse)


Samples = dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]]
"""Every vehicle's plan sampled once on a grid: {vehicle: (position (M, 3) m, velocity (M, 3) m/s,
acceleration (M, 3) m/s^2)} (:meth:`proxplan.planfile.VehicleTrajectory.sample`), shared by the
verifier's checks."""


def plan_samples(plan: Plan, t_s: np.ndarray) -> Samples:
    """:data:`Samples` of every vehicle of ``plan`` at times ``t_s`` (M,), s."""
    return {name: tr.sample(t_s) for name, tr in plan.vehicles.items()}


def moving_mask(plan: Plan, names: list[str], t_s: np.ndarray, samples: Samples | None = None) -> np.ndarray:
    """(N, M) True where vehicle ``names[i]`` moves at ``t_s`` (plan speed >= ``REST_SPEED_MPS``),
    from ``samples`` when given (on ``t_s``)."""
    vel = [samples[n][1] if samples is not None else plan.vehicles[n].sample(t_s)[1] for n in names]
    return np.stack([np.linalg.norm(v, axis=1) >= REST_SPEED_MPS for v in vel]).reshape(len(names), np.size(t_s))


def wrench_along_plan(
    plan: Plan, scenario: Scenario | None, *, t_s: np.ndarray, samples: Samples | None = None
) -> dict[str, WrenchAlongPlan]:
    """Per-vehicle disturbance wrench and authority usage at times ``t_s`` (M,), s, summed over
    every other vehicle as a source (those above it), evaluated with the model directly. Without
    a scenario the plan's own vehicle parameters and the default model options are used.

    Evaluated on the (target, source, sample) rows within the pair's reach, in batches per pair of
    vehicle types, stacks of sources together (:mod:`proxplan.verify.plan_wrench`); a source left
    out changes a usage by less than ``proxplan.verify.reach.NEGLIGIBLE_USAGE``. ``usage_by_source``
    holds the sources that are ever within reach of the vehicle (the others' usage is below that).
    ``samples``: the plan's :data:`Samples` on ``t_s``, if already taken."""
    t_s = np.asarray(t_s, dtype=float)
    names = list(plan.vehicles)
    pos = {n: s[0] for n, s in samples.items()} if samples is not None else plan.positions_at(t_s)
    vehicles = [_vehicle(plan, scenario, n) for n in names]
    effects = tuple(scenario.effects if scenario is not None else plan.effects)
    field = PlanWrench(np.stack([pos[n] for n in names]), vehicles, model_options(scenario), effects)
    out = {}
    for k, tname in enumerate(names):
        usage = authority_usage(vehicles[k], field.force[k], field.torque[k]) if t_s.size else np.zeros(0)
        by_source = UsageBySource(
            t_s.size, {names[s]: field.by_source[(k, s)] for s in range(len(names)) if (k, s) in field.by_source}
        )
        out[tname] = WrenchAlongPlan(t_s, field.force[k], field.torque[k], usage, by_source, field.invalid[k])
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
    """Smallest centre distance over non-dock pairs (and over docking pairs), m; None if < 2 vehicles.

    Per sample, each vehicle's nearest neighbours (``scipy.spatial.cKDTree``, as many as it has dock
    partners plus one) hold its nearest pair that counts; the distances are then those of the pairs."""
    from scipy.spatial import cKDTree

    t_s = plan.t_s if t_s is None else t_s
    pos = plan.positions_at(t_s)
    names = list(plan.vehicles)
    n = len(names)
    if n < 2 or np.size(t_s) == 0:
        return {"min_separation_m": None, "min_dock_separation_m": None}
    p = np.stack([pos[k] for k in names])  # (N, M, 3)
    index = {k: i for i, k in enumerate(names)}
    exempt: dict[tuple[int, int], np.ndarray] = {}  # dock pair (i < j) -> (M,) on its approach
    for name, task in scenario.vehicles.items():
        if task.dock_with is not None and name in index and task.dock_with in index:
            a, b = sorted((index[name], index[task.dock_with]))
            exempt[(a, b)] = dock_exempt(plan, scenario, names[a], names[b], pos, t_s)
    partners = np.zeros(n, dtype=int)
    for a, b in exempt:
        partners[a] += 1
        partners[b] += 1
    k = min(n, int(partners.max()) + 2)
    ii, jj, mm = [], [], []
    for m in range(p.shape[1]):
        _, idx = cKDTree(p[:, m]).query(p[:, m], k=k)
        ii.append(np.repeat(np.arange(n), k))
        jj.append(idx.ravel())
        mm.append(np.full(n * k, m))
    i, j, m_all = np.concatenate(ii), np.concatenate(jj), np.concatenate(mm)
    a, b = np.minimum(i, j)[i != j], np.maximum(i, j)[i != j]
    m_all = m_all[i != j]
    counted = np.ones(a.size, dtype=bool)
    for (da, db), ex in exempt.items():
        rows = (a == da) & (b == db)
        counted[rows] = ~ex[m_all[rows]]
    d = np.linalg.norm(p[a, m_all] - p[b, m_all], axis=1)
    best = float(d[counted].min()) if counted.any() else None
    docked = [np.linalg.norm(p[da] - p[db], axis=1)[ex] for (da, db), ex in exempt.items() if ex.any()]
    best_dock = float(min(x.min() for x in docked)) if docked else None
    return {"min_separation_m": best, "min_dock_separation_m": best_dock}
