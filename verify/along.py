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
from proxplan.physics import ModelOptions, authority_usage, invalid_zone_mask, shielding_reach_m
from proxplan.planfile import Plan, Scenario
from proxplan.verify.reach import MIN_DZ_M, counts_above, every_pair, pair_reach_m, pairs_within

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
    a scenario the plan's own vehicle parameters and the default model options are used.

    Evaluated on the (target, source, sample) rows within the pair's reach
    (:mod:`proxplan.verify.reach`; a source beyond it changes the usage by less than
    ``NEGLIGIBLE_USAGE``) in batches per pair of vehicle types; where two or more sources are above
    a target (any distance), the stack's rows are evaluated together by ``sources_wrench`` with
    every source within reach plus the shielding reach of one in reach (the sources that can shield
    it). ``usage_by_source`` holds the sources ever within reach of the vehicle."""
    t_s = np.asarray(t_s, dtype=float)
    names = list(plan.vehicles)
    pos = plan.positions_at(t_s)
    vehicles = [_vehicle(plan, scenario, n) for n in names]
    effects = tuple(scenario.effects if scenario is not None else plan.effects)
    field = _PlanWrench(np.stack([pos[n] for n in names]), vehicles, model_options(scenario), effects)
    out = {}
    for k, tname in enumerate(names):
        usage = authority_usage(vehicles[k], field.force[k], field.torque[k]) if t_s.size else np.zeros(0)
        by_source = {names[s]: field.by_source[(k, s)] for s in range(len(names)) if (k, s) in field.by_source}
        out[tname] = WrenchAlongPlan(t_s, field.force[k], field.torque[k], usage, by_source, field.invalid[k])
    return out


_PAD_OFFSET_M = np.array([1.0e3, 1.0e3, 1.0e3])  # a padding source far below the target: no wrench, m


class _PlanWrench:
    """The summed wrench ``force`` / ``torque`` (N, M, 3), the invalid zone ``invalid`` (N, M) and
    the usage of each source alone ``by_source`` {(target, source): (M,)} of vehicles at positions
    (N, M, 3), m (see :func:`wrench_along_plan`)."""

    def __init__(self, pos_m: np.ndarray, vehicles: list, options: ModelOptions, effects: tuple):
        n, m = pos_m.shape[:2]
        self.pos, self.options, self.effects = pos_m, options, effects
        self.kinds = list(dict.fromkeys(vehicles))
        self.kind = np.array([self.kinds.index(v) for v in vehicles], dtype=np.intp)
        self.force = np.zeros((n, m, 3))
        self.torque = np.zeros((n, m, 3))
        self.invalid = np.zeros((n, m), dtype=bool)
        self.by_source: dict[tuple[int, int], np.ndarray] = {}
        if n >= 2 and m:
            self._evaluate()

    def _evaluate(self) -> None:
        pos, kind, kinds = self.pos, self.kind, self.kinds
        n, m = pos.shape[:2]
        dz_max, r_max = plan_extent_m(pos)
        nk = len(kinds)
        reach = np.array(  # [source kind, target kind], m
            [[pair_reach_m(s, t, self.options, self.effects, dz_lo_m=0.0, dz_hi_m=dz_max, r_max_m=r_max) for t in kinds] for s in kinds]
        )  # fmt: skip
        below = (  # sources level with or below the target: only effects may act there
            np.array(
                [[pair_reach_m(s, t, self.options, self.effects, dz_lo_m=-dz_max, dz_hi_m=0.0, r_max_m=r_max) for t in kinds] for s in kinds]
            )  # fmt: skip
            if self.effects
            else np.zeros((nk, nk))
        )
        if every_pair(n, m):
            reach[:] = np.inf
            below[:] = np.inf if self.effects else 0.0
        stack = counts_above(pos[:, :, 2]) >= 2  # (N, M) the checks' "two or more sources above"
        eta = self.options.stack_shielding
        shield = (
            max(shielding_reach_m(a, b, eta, dz_max, self.options.discretisation) for a in kinds for b in kinds)
            if stack.any()
            else 0.0
        )
        rb = np.array([v.body_radius_m for v in kinds])[kind]
        pair_r = np.maximum(np.maximum(reach[kind][:, kind], reach[kind][:, kind].T), rb[:, None] + rb[None, :])
        slot_r = float(reach.max()) + shield if stack.any() else 0.0
        radius = np.maximum(np.maximum(pair_r, slot_r), np.maximum(below[kind][:, kind], below[kind][:, kind].T))
        ii, jj, mm = pairs_within(pos[:, :, :2], radius + 1e-9)
        tgt, src, smp = np.concatenate([ii, jj]), np.concatenate([jj, ii]), np.concatenate([mm, mm])
        off = pos[tgt, smp] - pos[src, smp]  # (R, 3) p_target - p_source
        dz = -off[:, 2]
        hor = np.hypot(off[:, 0], off[:, 1])
        ks, kt = kind[src], kind[tgt]
        pair = (dz > MIN_DZ_M) & (hor <= np.maximum(reach[ks, kt], rb[src] + rb[tgt]))
        self._pairs(tgt[pair], src[pair], smp[pair], off[pair], stack)
        need = np.zeros((n, m), dtype=bool)
        need[tgt[(dz > 0.0) & (hor <= reach[ks, kt])], smp[(dz > 0.0) & (hor <= reach[ks, kt])]] = True
        need &= stack
        if need.any():
            slot = need[tgt, smp] & (((dz > 0.0) & (hor <= slot_r)) | ((dz <= 0.0) & (hor <= below[ks, kt])))
            self._stacks(need, tgt[slot], src[slot], smp[slot], off[slot])

    def _pairs(self, tgt, src, smp, off, stack) -> None:
        """One source above the target: the pair wrench of every row, summed where no stack."""
        m = self.pos.shape[1]
        key = tgt * len(self.kind) + src
        for kk in np.unique(self.kind[src] * len(self.kinds) + self.kind[tgt]):
            sel = np.flatnonzero(self.kind[src] * len(self.kinds) + self.kind[tgt] == kk)
            source, target = self.kinds[kk // len(self.kinds)], self.kinds[kk % len(self.kinds)]
            f, tq = pair_wrench(source, target, off[sel], self.options, self.effects)
            u = authority_usage(target, f, tq)
            self.invalid[tgt[sel][invalid_zone_mask(source, target, off[sel])], smp[sel][invalid_zone_mask(source, target, off[sel])]] = True
            lone = ~stack[tgt[sel], smp[sel]]
            np.add.at(self.force, (tgt[sel][lone], smp[sel][lone]), f[lone])
            np.add.at(self.torque, (tgt[sel][lone], smp[sel][lone]), tq[lone])
            for k in np.unique(key[sel]):
                rows = key[sel] == k
                arr = self.by_source.setdefault((int(k) // len(self.kind), int(k) % len(self.kind)), np.zeros(m))
                arr[smp[sel][rows]] = u[rows]

    def _stacks(self, need, tgt, src, smp, off) -> None:
        """Two or more sources above: ``sources_wrench`` on batches of stack rows of one target type,
        each source type's slots padded to the batch's most (a padding source sits far below)."""
        nk = len(self.kinds)
        rows_t, rows_m = np.nonzero(need)
        row_id = np.full(need.shape, -1, dtype=np.intp)
        row_id[rows_t, rows_m] = np.arange(rows_t.size)
        rid = row_id[tgt, smp]
        sk = self.kind[src]
        order = np.lexsort((src, sk, rid))  # slots by row, source type, source
        rid, sk, off = rid[order], sk[order], off[order]
        group = rid * nk + sk
        start = np.r_[0, np.flatnonzero(np.diff(group)) + 1]
        rank = np.arange(group.size) - np.repeat(start, np.diff(np.r_[start, group.size]))
        count = np.zeros((rows_t.size, nk), dtype=np.intp)
        np.add.at(count, (rid, sk), 1)
        slot_of_row = np.r_[0, np.cumsum(count.sum(axis=1))]  # slots of row r: [slot_of_row[r], slot_of_row[r+1])
        for kt in np.unique(self.kind[rows_t]):
            mine = np.flatnonzero(self.kind[rows_t] == kt)
            mine = mine[np.argsort(count[mine].sum(axis=1), kind="stable")]  # similar rows together
            for b0 in range(0, mine.size, _STACK_BATCH):
                batch = mine[b0 : b0 + _STACK_BATCH]
                slots = np.concatenate([np.arange(slot_of_row[r], slot_of_row[r + 1]) for r in batch])
                local = np.repeat(np.arange(batch.size), count[batch].sum(axis=1))
                sources = []
                for k in range(nk):
                    width = int(count[batch, k].max())
                    if width == 0:
                        continue
                    padded = np.broadcast_to(_PAD_OFFSET_M, (width, batch.size, 3)).copy()
                    of_k = sk[slots] == k
                    padded[rank[slots][of_k], local[of_k]] = off[slots][of_k]
                    sources += [(self.kinds[k], padded[c]) for c in range(width)]
                f, tq = sources_wrench(self.kinds[kt], sources, self.options, self.effects)
                self.force[rows_t[batch], rows_m[batch]] = f
                self.torque[rows_t[batch], rows_m[batch]] = tq


_STACK_BATCH = 2048  # stack rows per sources_wrench call


def plan_extent_m(pos_m: np.ndarray) -> tuple[float, float]:
    """(largest height difference, horizontal diagonal of the bounding box), m, of positions
    (N, M, 3), m: the vertical and horizontal ranges a pair's reach must cover."""
    lo, hi = pos_m.reshape(-1, 3).min(axis=0), pos_m.reshape(-1, 3).max(axis=0)
    return float(hi[2] - lo[2]), float(np.hypot(hi[0] - lo[0], hi[1] - lo[1]))


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
