"""The disturbance wrench on every vehicle of a plan from every other vehicle above it, vectorised
over vehicle pairs and stacks (the engine of :func:`proxplan.verify.along.wrench_along_plan`).

The model is evaluated on the (target, source, sample) rows within the pair's reach
(:mod:`proxplan.verify.reach`: a source beyond it changes the target's authority usage by less
than ``NEGLIGIBLE_USAGE``), in batches per pair of vehicle types, with
:func:`proxplan.costmaps.pair_wrench`. Where a target has one source above it (by more than
1e-6 m, counted over every vehicle) its wrench is that pair's; where it has two or more, the
stack's (``proxplan.costmaps.sources_wrench``: each upper jet scaled by what the sources between
let pass, :mod:`proxplan.physics.stack`, S0's superposition otherwise):

* without effects between vehicles, as the base model composes it: the sum over the sources in
  reach of s_j times the pair wrench, s_j the product over the vehicles k between source j and the
  target of :func:`proxplan.physics.stack.pass_through_share`, evaluated once per (j, k, sample)
  for the pairs within the shielding reach (beyond it the share is exactly 1.0) and shared by
  every target below;
* with effects (which need not add up over sources), ``sources_wrench`` itself on batches of
  stack rows, with every source within reach plus the shielding reach as a slot (each vehicle
  type's slots padded to the batch's most by a source far below, which contributes nothing).

Frames and units as :mod:`proxplan.verify.along`: world frame, z up; m, N, N m.
"""

from __future__ import annotations

import numpy as np

from proxplan.costmaps import pair_wrench, sources_wrench
from proxplan.physics import ModelOptions, authority_usage, invalid_zone_mask, pass_through_share, shielding_reach_m
from proxplan.verify.reach import (
    MIN_DZ_M,
    NEGLIGIBLE_USAGE,
    UsageGrid,
    counts_above,
    every_pair,
    pairs_within,
    usage_grid,
)

_PAD_OFFSET_M = np.array([1.0e3, 1.0e3, 1.0e3])  # a padding source far below the target: no wrench, m
_STACK_BATCH = 2048  # stack rows per sources_wrench call


def plan_extent_m(pos_m: np.ndarray) -> tuple[float, float]:
    """(largest height difference, horizontal diagonal of the bounding box), m, of positions
    (N, M, 3), m: the vertical and horizontal ranges a pair's reach must cover."""
    flat = pos_m.reshape(-1, 3)
    lo, hi = flat.min(axis=0), flat.max(axis=0)
    return float(hi[2] - lo[2]), float(np.hypot(hi[0] - lo[0], hi[1] - lo[1]))


def oriented_rows(pos_m: np.ndarray, ii, jj, mm, *, both: bool) -> tuple[np.ndarray, ...]:
    """(target, source, sample, offset p_target - p_source (R, 3), m) of the pair rows (ii, jj, mm):
    each pair as (lower, upper), the source strictly above (dz > 0) where one is (``both``: each
    pair both ways). The offset of a flipped row is the negated one (exactly p_jj - p_ii)."""
    off = pos_m[ii, mm] - pos_m[jj, mm]  # ii as the target
    if both:
        return np.concatenate([ii, jj]), np.concatenate([jj, ii]), np.concatenate([mm, mm]), np.concatenate([off, -off])
    flip = -off[:, 2] <= 0.0  # jj not above ii: jj is the target (if either is)
    return np.where(flip, jj, ii), np.where(flip, ii, jj), mm, np.where(flip[:, None], -off, off)


def _kinds(vehicles: list) -> tuple[list, np.ndarray]:
    """The distinct vehicles (in order of first use) and each vehicle's index among them."""
    kinds = list(dict.fromkeys(vehicles))
    return kinds, np.array([kinds.index(v) for v in vehicles], dtype=np.intp)


class PlanWrench:
    """``force`` / ``torque`` (N, M, 3), N / N m, summed over the sources above each vehicle;
    ``invalid`` (N, M) in a source's invalid zone; ``by_source`` {(target, source): (samples (R,),
    usage (R,))} authority usage of each source alone on the samples where it is in reach (rising
    sample indices; 0 on the others; sources ever within reach), for ``vehicles`` (N) at positions
    ``pos_m`` (N, M, 3), m, with the model ``options`` and between-vehicle ``effects``. (Stored over
    the samples in reach only: an (M,) array per pair ever in reach held 377 MB on grid-256.)"""

    def __init__(self, pos_m: np.ndarray, vehicles: list, options: ModelOptions, effects: tuple):
        n, m = pos_m.shape[:2]
        self.pos, self.options, self.effects = pos_m, options, tuple(effects)
        self.kinds, self.kind = _kinds(vehicles)
        self.force = np.zeros((n, m, 3))
        self.torque = np.zeros((n, m, 3))
        self.invalid = np.zeros((n, m), dtype=bool)
        self.by_source: dict[tuple[int, int], tuple[np.ndarray, np.ndarray]] = {}
        if n >= 2 and m:
            self._evaluate()

    def _grids(self, dz_lo_m: float, dz_hi_m: float, r_max_m: float) -> list[list[UsageGrid]]:
        """[source kind][target kind] usage grids (verify.reach.usage_grid)."""
        return [
            [usage_grid(s, t, self.options, self.effects, dz_lo_m=dz_lo_m, dz_hi_m=dz_hi_m, r_max_m=r_max_m)
             for t in self.kinds] for s in self.kinds
        ]  # fmt: skip

    def _evaluate(self) -> None:
        pos, kind, nk = self.pos, self.kind, len(self.kinds)
        n, m = pos.shape[:2]
        dz_max, r_max = plan_extent_m(pos)
        every = every_pair(n, m)
        grids = None if every else self._grids(0.0, dz_max, r_max)
        reach = np.full((nk, nk), np.inf) if grids is None else np.array([[g.reach_m for g in row] for row in grids])
        below = np.zeros((nk, nk))  # sources level with or below the target: only effects act there (stacks)
        if self.effects:
            below = np.full((nk, nk), np.inf) if every else self._reach_of(self._grids(-dz_max, 0.0, r_max))
        stack = counts_above(pos[:, :, 2]) >= 2  # (N, M) the checks' "two or more sources above"
        self.shield = self._shield_reach(dz_max) if stack.any() else np.zeros((nk, nk))
        rb = np.array([v.body_radius_m for v in self.kinds])[kind]
        radius = np.maximum(np.maximum(reach[kind][:, kind], reach[kind][:, kind].T), rb[:, None] + rb[None, :])
        if self.effects and stack.any():  # sources_wrench slots below the target, within the effects' reach
            radius = np.maximum(radius, np.maximum(below[kind][:, kind], below[kind][:, kind].T))
        ii, jj, mm = pairs_within(pos[:, :, :2], radius + 1e-9)
        tgt, src, smp, off = oriented_rows(pos, ii, jj, mm, both=bool(self.effects))
        dz = -off[:, 2]
        hor = np.hypot(off[:, 0], off[:, 1])
        ks, kt = kind[src], kind[tgt]
        self._invalid(np.flatnonzero((dz > MIN_DZ_M) & (hor < rb[src] + rb[tgt])), tgt, src, smp, off)
        near = dz > 0.0
        if grids is not None:  # in reach and, by the grid's bound at this very dz, not negligible
            near &= hor <= reach[ks, kt]
            for g in np.unique(ks * nk + kt):
                sel = np.flatnonzero(near & (ks * nk + kt == g))
                near[sel] = grids[g // nk][g % nk].bound(hor[sel], dz[sel], dz[sel]) >= NEGLIGIBLE_USAGE
        rows = np.flatnonzero(near)
        force, torque = self._pairs(tgt[rows], src[rows], smp[rows], off[rows], stack)
        if not stack.any():
            return
        if not self.effects:
            at_stack = stack[tgt[rows], smp[rows]]
            self._stacks_shielded(tgt[rows][at_stack], src[rows][at_stack], smp[rows][at_stack],
                                  force[at_stack], torque[at_stack])  # fmt: skip
            return
        # effects: sources_wrench on each stack row with its sources in reach, those that may
        # shield one of them and those below within the effects' reach
        need = np.zeros((n, m), dtype=bool)
        low = np.flatnonzero((dz <= 0.0) & (hor <= below[ks, kt]))
        need[tgt[rows], smp[rows]] = True
        need[tgt[low], smp[low]] = True
        need &= stack
        lead = rows[need[tgt[rows], smp[rows]]]
        slot_t, slot_s, slot_m = [tgt[lead]], [src[lead]], [smp[lead]]
        if self.options.stack_shielding > 0.0:
            u, k, mm, _ = self._shield_pairs(tgt[lead], src[lead], smp[lead])
            row, pair = self._between(tgt[lead], src[lead], smp[lead], u, k, mm)
            slot_t, slot_s, slot_m = slot_t + [tgt[lead][row]], slot_s + [k[pair]], slot_m + [smp[lead][row]]
        low = low[need[tgt[low], smp[low]]]
        slot_t, slot_s, slot_m = slot_t + [tgt[low]], slot_s + [src[low]], slot_m + [smp[low]]
        key = np.unique((np.concatenate(slot_t) * n + np.concatenate(slot_s)) * m + np.concatenate(slot_m))
        st, ss, sm = key // m // n, key // m % n, key % m
        self._stacks_together(need, st, ss, pos[st, sm] - pos[ss, sm], sm)

    @staticmethod
    def _reach_of(grids: list[list[UsageGrid]]) -> np.ndarray:
        return np.array([[g.reach_m for g in row] for row in grids])

    def _invalid(self, rows: np.ndarray, tgt, src, smp, off) -> None:
        """Mark the rows (source above by more than 1e-6 m) inside the source's invalid zone."""
        nk = len(self.kinds)
        group = self.kind[src[rows]] * nk + self.kind[tgt[rows]]
        for g in np.unique(group):
            sel = rows[group == g]
            inside = sel[invalid_zone_mask(self.kinds[g // nk], self.kinds[g % nk], off[sel])]
            self.invalid[tgt[inside], smp[inside]] = True

    def _shield_reach(self, dz_max: float) -> np.ndarray:
        """[upper kind, middle kind] shielding reach, m (physics.stack.shielding_reach_m)."""
        eta, disc = self.options.stack_shielding, self.options.discretisation
        return np.array([[shielding_reach_m(u, k, eta, dz_max, disc) for k in self.kinds] for u in self.kinds])

    def _pairs(self, tgt, src, smp, off, stack) -> tuple[np.ndarray, np.ndarray]:
        """The pair wrench of every row (source above the target); rows above by more than 1e-6 m
        give the usage by source, and make the sum where no stack."""
        nk, n = len(self.kinds), len(self.kind)
        force, torque = np.zeros((tgt.size, 3)), np.zeros((tgt.size, 3))
        group = self.kind[src] * nk + self.kind[tgt]
        for g in np.unique(group):
            sel = np.flatnonzero(group == g)
            source, target = self.kinds[g // nk], self.kinds[g % nk]
            force[sel], torque[sel] = pair_wrench(source, target, off[sel], self.options, self.effects)
            above = sel[-off[sel, 2] > MIN_DZ_M]
            u = authority_usage(target, force[above], torque[above])
            key, at = tgt[above] * n + src[above], smp[above]
            order = np.lexsort((at, key))  # by (target, source), then sample
            for rows in np.split(order, np.flatnonzero(np.diff(key[order])) + 1):  # one (target, source) each
                if rows.size:
                    self.by_source[(int(key[rows[0]]) // n, int(key[rows[0]]) % n)] = (at[rows], u[rows])
        lone = np.flatnonzero((-off[:, 2] > MIN_DZ_M) & ~stack[tgt, smp])  # at most one source above
        self.force[tgt[lone], smp[lone]] = force[lone]
        self.torque[tgt[lone], smp[lone]] = torque[lone]
        return force, torque

    def _shield_pairs(self, tgt, src, smp) -> tuple[np.ndarray, ...]:
        """(u, k, sample, p_k - p_u (T, 3), m): every upper u and middle k within the shielding
        reach, k lower than u (by more than 1e-6 m) and higher than the lowest target of the rows
        (target, source u, sample) then (else k is between u and none of them), by (u, sample, k)."""
        pos, kind = self.pos, self.kind
        m = pos.shape[1]
        ii, jj, mm = pairs_within(pos[:, :, :2], np.maximum(self.shield, self.shield.T)[kind][:, kind] + 1e-9)
        up = pos[ii, mm, 2] - pos[jj, mm, 2] > 0.0
        u, k = np.where(up, ii, jj), np.where(up, jj, ii)
        mid = pos[k, mm] - pos[u, mm]
        lowest = np.full((len(kind), m), np.inf)  # per (source, sample) of the rows, m
        np.minimum.at(lowest, (src, smp), pos[tgt, smp, 2])
        keep = (-mid[:, 2] > MIN_DZ_M) & (pos[k, mm, 2] - lowest[u, mm] > MIN_DZ_M)
        order = np.flatnonzero(keep)[np.lexsort((k[keep], mm[keep], u[keep]))]
        return u[order], k[order], mm[order], mid[order]

    def _between(self, tgt, src, smp, u, k, mm) -> tuple[np.ndarray, np.ndarray]:
        """(row, pair): for the rows (target, source j, sample), each shield pair (j, k, sample) of
        :meth:`_shield_pairs` (sorted) whose k is between j and the target (both above the target
        by more than 1e-6 m), rows ascending and, within a row, k ascending."""
        pos, m = self.pos, self.pos.shape[1]
        key = u * m + mm
        lo = np.searchsorted(key, src * m + smp, side="left")
        count = np.searchsorted(key, src * m + smp, side="right") - lo
        row = np.repeat(np.arange(tgt.size), count)
        pair = np.repeat(lo, count) + np.arange(row.size) - np.repeat(np.cumsum(count) - count, count)
        z_t = pos[tgt[row], smp[row], 2]
        between = (pos[k[pair], mm[pair], 2] - z_t > MIN_DZ_M) & (pos[src[row], smp[row], 2] - z_t > MIN_DZ_M)
        return row[between], pair[between]

    def _stacks_shielded(self, tgt, src, smp, force, torque) -> None:
        """Stack rows without effects: sum over the sources j of s_j times the pair wrench."""
        kind, nk = self.kind, len(self.kinds)
        eta = self.options.stack_shielding
        share = np.ones(tgt.size)
        if eta > 0.0:
            u, k, mm, mid = self._shield_pairs(tgt, src, smp)
            value = np.ones(u.size)
            group = kind[u] * nk + kind[k]
            for g in np.unique(group):
                sel = group == g
                value[sel] = pass_through_share(self.kinds[g // nk], self.kinds[g % nk], mid[sel], eta,
                                                self.options.discretisation)  # fmt: skip
            keep = value != 1.0  # a factor of exactly 1.0 changes nothing
            u, k, mm, value = u[keep], k[keep], mm[keep], value[keep]
            row, pair = self._between(tgt, src, smp, u, k, mm)
            np.multiply.at(share, row, value[pair])  # per row in the order of k
        order = np.lexsort((src, smp, tgt))  # per (target, sample) in the order of the sources
        np.add.at(self.force, (tgt[order], smp[order]), force[order] * share[order, None])
        np.add.at(self.torque, (tgt[order], smp[order]), torque[order] * share[order, None])

    def _stacks_together(self, need, tgt, src, off, smp) -> None:
        """Stack rows with effects: ``sources_wrench`` on batches of stack rows of one target type,
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
        first_slot = np.r_[0, np.cumsum(count.sum(axis=1))]  # slots of row r: first_slot[r] .. first_slot[r + 1]
        for kt in np.unique(self.kind[rows_t]):
            mine = np.flatnonzero(self.kind[rows_t] == kt)
            mine = mine[np.argsort(count[mine].sum(axis=1), kind="stable")]  # similar rows together
            for b0 in range(0, mine.size, _STACK_BATCH):
                batch = mine[b0 : b0 + _STACK_BATCH]
                slots = np.concatenate([np.arange(first_slot[r], first_slot[r + 1]) for r in batch])
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
