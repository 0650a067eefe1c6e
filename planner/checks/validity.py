"""Vectorised validity of many states of one vehicle against all other (moving) vehicles.

:class:`BatchChecker` holds the same constraints as a :class:`proxplan.planner.checks.constraints.ConflictChecker`
(workspace, inflated obstacles, separation, downwash cut-offs both ways, keep-out ellipsoid) as numpy
arrays: every other vehicle's track resampled on one time grid (V, K, 3), m, and its cut-off tables
padded into (V, L) arrays, m. ``first_conflict`` checks M states (x, y, z, t) against all V vehicles
in one numpy evaluation of (M, V) arrays and gives the same verdict (and the same constraint name)
as the scalar ``ConflictChecker.conflict`` applied state by state (a test compares both on random
states).

A time-binned index keeps each call small: for every vehicle and every ``bin_s`` of time the
bounding box of its track is stored, and a batch of states only meets the vehicles whose box, grown
by their largest reach (separation, cut-off or ellipsoid radius, m), overlaps the batch's box in x/y
during the batch's time span.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from proxplan.planner.checks.constraints import ConflictChecker, CutoffTable

BIN_S = 0.5  # time bin of the spatial index, s


def bracket_table(table: CutoffTable | None, tube_m: float = 0.0) -> tuple[np.ndarray, float]:
    """A cut-off table as an array (K,) of the radius ``table.lookup`` gives in each dz step (the
    larger bracketing sample; 0 in the last step), m, grown by the tracking tube ``tube_m`` (m) to
    the largest radius over dz +- tube as :meth:`PairRule.cutoff_m`; and its dz step, m (an empty
    array and inf without a table)."""
    if table is None:
        return np.zeros(0), math.inf
    arr = np.asarray(table.r_cut_m, dtype=float)
    pair = np.zeros(arr.size)  # lookup(dz) = max(arr[k], arr[k + 1]) while k + 1 < size
    pair[:-1] = np.maximum(arr[:-1], arr[1:])
    if tube_m > 0.0:  # tracking tube: the largest radius over dz +- tube (PairRule.cutoff_m)
        reach = int(math.ceil(tube_m / float(table.dz_step_m) - 1e-9))
        grown = pair.copy()
        for j in range(1, min(reach, pair.size - 1) + 1):
            grown[:-j] = np.maximum(grown[:-j], pair[j:])
            grown[j:] = np.maximum(grown[j:], pair[:-j])
        pair = grown
    return pair, float(table.dz_step_m)


def stack_tables(tables: list[np.ndarray]) -> np.ndarray:
    """Bracket tables (:func:`bracket_table`) as rows of one (R, W) array, m, zero-padded with at
    least one last column of zeros, so that a lookup beyond a table gives 0."""
    width = max([t.size for t in tables] + [1]) + 1
    out = np.zeros((len(tables), width))
    for i, t in enumerate(tables):
        out[i, : t.size] = t
    return out


def cutoff_lookup(cut: np.ndarray, step: np.ndarray, row: np.ndarray, dz_m: np.ndarray) -> np.ndarray:
    """Cut-off radius (m) of table row ``row`` of ``cut`` (R, W) (:func:`stack_tables`, dz steps
    ``step`` (R,), m) at vertical distance ``|dz_m|``; ``row`` and ``dz_m`` broadcast."""
    width = cut.shape[1]
    k = np.minimum(np.abs(dz_m) / step[row], width - 1).astype(int)
    return cut.ravel()[row * width + k]


def rule_kind(
    r2: np.ndarray, dz: np.ndarray, active: np.ndarray, sep2: np.ndarray, ell2: np.ndarray, rc: np.ndarray
) -> np.ndarray:
    """The first pair rule a state breaks against another vehicle, as ``ConflictChecker.conflict``
    orders them: 0 separation, 1 ellipsoid of the other or downwash of the other (it is above), 2
    downwash on the other (it is below), -1 none. Arrays broadcast: squared horizontal distance
    ``r2`` (m^2), vertical offset ``dz`` = own z - other's z (m), ``active`` (the other is present),
    squared separation ``sep2`` and ellipsoid radius ``ell2`` (m^2, nan: no ellipsoid rule, then
    the cut-off rule applies), cut-off radius ``rc`` looked up for ``dz``'s direction (m, 0: none)."""
    sep = active & (r2 + dz * dz < sep2)
    has_ell = ~np.isnan(ell2)
    with np.errstate(invalid="ignore"):
        ell = active & has_ell & (r2 / ell2 + dz * dz / (9.0 * ell2) < 1.0)
    up = dz > 0.0
    down = active & ~has_ell & (dz != 0.0) & (r2 < rc * rc)
    below = down & ~up
    above = down & up
    return np.where(sep, 0, np.where(ell | below, 1, np.where(above, 2, -1)))


@dataclass(frozen=True)
class BatchChecker:
    """Array form of one :class:`ConflictChecker` (see the module docstring)."""

    checker: ConflictChecker
    names: tuple[str, ...]  # (V,) other vehicles in rule order
    dt_s: float  # time step of ``pos``, s
    pos: np.ndarray  # (V, K, 3) positions, m, last sample held beyond a track's end
    until_s: np.ndarray  # (V,) presence ends (incl. the rule's margin), s
    sep2: np.ndarray  # (V,) squared separation, m^2
    ell2: np.ndarray  # (V,) squared ellipsoid radius, m^2 (nan: no ellipsoid rule)
    cut_both: np.ndarray  # (2V, L): rows 0..V-1 r_cut(dz) (bracket maximum) of the other above us,
    # rows V..2V-1 ours on the other below, m; 0 beyond a table (last column always 0)
    step_both: np.ndarray  # (2V,) dz step of each row, m (inf: no table)
    margin: np.ndarray  # (V,) margin added to a positive cut-off radius, m
    reach: np.ndarray  # (V,) largest horizontal distance at which the vehicle can conflict, m
    box_lo: np.ndarray  # (V, B, 2) x/y minimum of the track per time bin, m
    box_hi: np.ndarray  # (V, B, 2)
    bin_s: float  # time bin of the index, s
    lo: np.ndarray  # (3,) workspace bounds (body margin included), m
    hi: np.ndarray
    boxes: np.ndarray  # (O, 6) inflated obstacles, m

    @classmethod
    def from_checker(cls, checker: ConflictChecker, *, dt_s: float | None = None) -> BatchChecker:
        rules = checker.rules
        v = len(rules)
        dts = [r.track.dt_s for r in rules if len(r.track.x) > 1]
        dt = float(dt_s if dt_s is not None else (min(dts) if dts else 1.0))
        k = max([int(math.ceil(r.track.end_s / dt - 1e-9)) + 1 for r in rules] + [1])
        pos = np.empty((v, k, 3))
        tk = np.arange(k) * dt
        for i, r in enumerate(rules):
            tr = r.track
            if len(tr.x) == 1:
                pos[i] = (tr.x[0], tr.y[0], tr.z[0])
            elif abs(tr.dt_s - dt) < 1e-12:
                n = len(tr.x)
                arr = np.column_stack([tr.x, tr.y, tr.z])
                pos[i, :n] = arr[:k]
                pos[i, n:] = arr[-1]
            else:
                pos[i] = [tr.at(float(t)) for t in tk]

        tabs_from = [bracket_table(r.cut_from_other, r.tube_m) for r in rules]
        tabs_on = [bracket_table(r.cut_on_other, r.tube_m) for r in rules]
        cut_both = stack_tables([t[0] for t in tabs_from + tabs_on])
        cut_from, cut_on = cut_both[:v], cut_both[v:]
        sep = np.array([r.separation_m for r in rules], dtype=float)
        ell = np.array([np.nan if r.ellipsoid_r_m is None else r.ellipsoid_r_m for r in rules], dtype=float)
        margin = np.array([r.margin_m + r.tube_m for r in rules], dtype=float)  # tube as in PairRule.cutoff_m
        reach = np.maximum.reduce(
            [sep, np.nan_to_num(ell, nan=0.0), cut_from.max(axis=1, initial=0.0), cut_on.max(axis=1, initial=0.0)]
        )
        reach = reach + margin + 1e-6
        per = max(1, int(round(BIN_S / dt)))
        nb = max(1, int(math.ceil(k / per)))
        box_lo = np.empty((v, nb + 1, 2))
        box_hi = np.empty((v, nb + 1, 2))
        for b in range(nb + 1):
            a, e = b * per, min(k, (b + 1) * per + 1)
            seg = pos[:, a:e, :2] if a < k else pos[:, -1:, :2]
            box_lo[:, b] = seg.min(axis=1)
            box_hi[:, b] = seg.max(axis=1)
        return cls(
            checker=checker,
            names=tuple(r.track.name for r in rules),
            dt_s=dt,
            pos=pos,
            until_s=np.array([r.track.until_s + r.until_margin_s for r in rules], dtype=float),
            sep2=sep * sep,
            ell2=ell * ell,
            cut_both=cut_both,
            step_both=np.array([t[1] for t in tabs_from + tabs_on], dtype=float),
            margin=margin,
            reach=reach,
            box_lo=box_lo,
            box_hi=box_hi,
            bin_s=per * dt,
            lo=np.asarray(checker.lo, dtype=float),
            hi=np.asarray(checker.hi, dtype=float),
            boxes=np.asarray(checker.boxes, dtype=float).reshape(-1, 6),
        )

    # -- index ---------------------------------------------------------------------------------
    def nearby(self, xyz: np.ndarray, t: np.ndarray) -> np.ndarray:
        """Indices of the vehicles that can conflict with any of the states (time-binned boxes)."""
        if not self.names:
            return np.zeros(0, dtype=int)
        nb = self.box_lo.shape[1]
        b0 = min(nb - 1, max(0, int(float(t.min()) / self.bin_s)))
        b1 = min(nb - 1, max(0, int(float(t.max()) / self.bin_s)))
        lo = self.box_lo[:, b0 : b1 + 1].min(axis=1) - self.reach[:, None]  # (V, 2)
        hi = self.box_hi[:, b0 : b1 + 1].max(axis=1) + self.reach[:, None]
        qlo, qhi = xyz[:, :2].min(axis=0), xyz[:, :2].max(axis=0)
        hit = np.all((lo <= qhi) & (hi >= qlo), axis=1)
        return np.nonzero(hit)[0]

    # -- checks --------------------------------------------------------------------------------
    def conflict_codes(
        self, xyz: np.ndarray, t: np.ndarray, *, exclude: str | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Per state the first violated constraint as (static code, vehicle code).

        Static code: -1 valid, 0 workspace, 1 + i obstacle i. Vehicle code: -1 none, else
        ``3 * v + kind`` with kind 0 separation, 1 ellipsoid / downwash of v, 2 downwash on v,
        v in rule order. The static code takes precedence (as in ``ConflictChecker.conflict``).
        """
        xyz = np.asarray(xyz, dtype=float).reshape(-1, 3)
        t = np.asarray(t, dtype=float).reshape(-1)
        m = xyz.shape[0]
        x, y, z = xyz[:, 0], xyz[:, 1], xyz[:, 2]
        static = np.full(m, -1, dtype=int)
        inside = np.all((xyz >= self.lo) & (xyz <= self.hi), axis=1)
        if self.boxes.size:
            inb = np.all(
                (xyz[:, None, :] >= self.boxes[None, :, :3]) & (xyz[:, None, :] <= self.boxes[None, :, 3:]), axis=2
            )
            anyb = inb.any(axis=1)
            static[anyb] = 1 + np.argmax(inb[anyb], axis=1)
        static[~inside] = 0
        code = np.full(m, -1, dtype=int)
        idx = self.nearby(xyz, t)
        if exclude is not None:
            idx = idx[[self.names[i] != exclude for i in idx]]
        if idx.size == 0:
            return static, code
        u = np.clip(t / self.dt_s, 0.0, None)
        kk = self.pos.shape[1]
        k0 = np.minimum(u.astype(int), kk - 1)
        k1 = np.minimum(k0 + 1, kk - 1)
        f = (u - k0)[None, :, None]
        p = self.pos[idx]  # (v, K, 3)
        a = p[:, k0]
        other = a + f * (p[:, k1] - a)  # (v, M, 3), as Track.at
        dx = x[None, :] - other[..., 0]
        dy = y[None, :] - other[..., 1]
        dz = z[None, :] - other[..., 2]
        r2 = dx * dx + dy * dy
        active = t[None, :] < self.until_s[idx, None]
        # one cut-off lookup: the other's table on us when it is above (dz < 0), ours on it when below
        row = idx[:, None] + len(self.names) * (dz > 0.0)  # (v, M) rows of cut_both
        rc = cutoff_lookup(self.cut_both, self.step_both, row, dz)
        rc = np.where(rc > 0.0, rc + self.margin[idx, None], 0.0)
        kind = rule_kind(r2, dz, active, self.sep2[idx, None], self.ell2[idx, None], rc)  # (v, M)
        hit = kind >= 0
        anyhit = hit.any(axis=0)
        first = np.argmax(hit, axis=0)  # first vehicle in rule order (idx is sorted)
        cols = np.nonzero(anyhit)[0]
        code[cols] = 3 * idx[first[cols]] + kind[first[cols], cols]
        return static, code

    def name_of(self, static: int, code: int) -> str | None:
        """The constraint name ``ConflictChecker.conflict`` would report."""
        if static == 0:
            return "workspace"
        if static > 0:
            return f"obstacle[{static - 1}]"
        if code < 0:
            return None
        v, kind = divmod(int(code), 3)
        name = self.names[v]
        if kind == 0:
            return f"separation from {name}"
        if kind == 1:
            return f"ellipsoid of {name}" if not math.isnan(self.ell2[v]) else f"downwash of {name}"
        return f"downwash on {name}"

    def conflicts(self, xyz: np.ndarray, t: np.ndarray, *, exclude: str | None = None) -> list[str | None]:
        """The constraint name (or None) of every state, like ``ConflictChecker.conflict``."""
        static, code = self.conflict_codes(xyz, t, exclude=exclude)
        return [self.name_of(int(s), int(c)) for s, c in zip(static, code)]

    def first_conflict(
        self, xyz: np.ndarray, t: np.ndarray, *, exclude: str | None = None, count: bool = False
    ) -> tuple[int, str | None]:
        """Index and name of the first invalid state (-1, None when all are valid).

        ``count``: add the rejection to the checker's statistics (``most_rejected``)."""
        static, code = self.conflict_codes(xyz, t, exclude=exclude)
        bad = (static >= 0) | (code >= 0)
        if not bad.any():
            return -1, None
        i = int(np.argmax(bad))
        name = self.name_of(int(static[i]), int(code[i]))
        if count and name is not None:
            kind = name.split(" ")[0] if not name.startswith("obstacle") else "obstacle"
            key = name if kind in ("separation", "downwash", "ellipsoid") else kind
            rej = self.checker.rejections
            rej[key] = rej.get(key, 0) + 1
        return i, name

    def all_valid(self, xyz: np.ndarray, t: np.ndarray, *, exclude: str | None = None, count: bool = False) -> bool:
        return self.first_conflict(xyz, t, exclude=exclude, count=count)[0] < 0
