"""Keep-out region of an ordered pair of vehicle types, vectorised, for the swarm layer.

Relative vector d = p_b - p_a (world frame, m). The pair conflicts when

* |d| < separation (max(limits.min_separation_m, r_a + r_b)) + w, or
* b is below a (d_z < 0) and r = |d_xy| < r_cut_{a->b}(-d_z) grown by w, or
* b is above a (d_z > 0) and r < r_cut_{b->a}(d_z) grown by w,

where r_cut is the cost map's cut-off radius at ``limits.authority_fraction`` with the scenario's
invalid-zone rule (:func:`proxplan.planner.checks.constraints.cutoff_table`, the planner's own tables) and
"grown by w" means the largest value over dz +- w plus w (as
:meth:`proxplan.planner.checks.constraints.PairRule.cutoff_m` does for the tracking tube); within
|d_z| <= w both directions apply. w = tracking tube ``limits.tracking_margin_m`` + ``sample_m`` (a
growth that covers how positions are compared: whole millimetres in the synchronous table,
:data:`proxplan.planner.swarm.problem.GROWTH_M`); at rest (both vehicles hold still) w = 0, as
the verifier leaves the tube out for resting pairs. A pair's predicted deflections (a vehicle
pushed off its plan by the downwash it flies in, or off its reference by its tracking error) grow
both, as in the verifier, each by what it can be while moving and while held
(``deflection_m``, ``rest_deflection_m`` of :func:`keepout_for`).

**Where the jet undamps the loop** (:func:`undamped_radius_m`; issue 37, round 18A). The cut-off
bounds the authority the jet uses, not what it does to the target's closed loop: right below a
lighter source (a Crazyflie's jet on the 145 g small quad uses 6-8 % of its authority, under the
10 % cut-off) the jet's gradients make the target's loop undamped (rightmost pole +0.16 to +0.45
1/s at 0.8 Hz), and the verifier, which drives the loop along the plan
(:mod:`proxplan.verify.jet_loop`), predicts a deflection that grows for as long as the target stays
there (pillar-128, grid-256: 0.1-0.22 m after 3-11 s; the plans failed ``verify``). So each
table, grown as above, also holds the relative positions out to which the target's loop held in
the source's jet is not damped (the verifier's own test, :func:`proxplan.verify.jet_loop.hold_poles`'s
pole), not grown by the tube: the verifier takes the loop's gradients at the planned positions.
The search costs about 0.4 s of CPU per ordered pair, so the built-in pairs' tables are shipped
(:data:`SHIPPED_LEVELS`; :mod:`proxplan.planner.swarm.zone_store`, keyed on every fact of
:func:`zone_facts`) and a table is searched only when its key misses (issue 37, round 19A).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

# the undamped zone is searched where the source's jet uses at least this share of the target's
# authority (the cost map's r_cut at this level bounds the scan outward). Set on the model, not on a
# layout (docs/planner.md, round 18A): over the built-in types' nine ordered pairs (crazyflie-2.1,
# crazyflie-parrot, small-quad; up to 3000 points per band of usage, azimuths 0, 22.5 and 45 degrees)
# undamped points use 1-3 % of the authority for three pairs (crazyflie-2.1 and -parrot over
# small-quad, small-quad over itself) and >= 3 % for the others; between 1 % and 1e-6 none was found,
# the rightmost pole there is the vehicle's own loop's (-0.0083 1/s). (The verifier runs the loop
# with the jet wherever the usage is >= 1e-6, jet_loop.WEAK_USAGE.) No margin below 1 %: a lower
# level with a finer step near the axis is the next step (its CPU not measured).
UNDAMPED_SCAN_USAGE = 1e-2
# radial step of that search, m: at least this, and at least 1/UNDAMPED_ROW_SAMPLES of the row's
# span (deep rows, where the jet at 1-10 % of the authority is 0.7-0.9 m wide, hold most samples at
# a fine step, none of them undamped); the radius found is rounded up to the next sample. A 2 cm
# step found 1 cm less of crazyflie-parrot over small-quad's zone than 5 mm does, in the same CPU
UNDAMPED_STEP_M = 0.005
UNDAMPED_ROW_SAMPLES = 8
# azimuths of the search (rad): the X-frame target and the axisymmetric jet make every other azimuth
# a mirror image of one in [0, pi/4] (as the cost map, costmaps/cutoff.py); its two ends are searched
UNDAMPED_AZIMUTHS_RAD = (0.0, np.pi / 4)
# the tables shipped (ship_undamped_zones, module zone_store): every ordered pair of built-in vehicles at these
# authority levels (planner/formations.py's layouts: 0.1; planfile Limits' default: 0.5), the
# default invalid-zone rule, the default field form and no effects
SHIPPED_LEVELS = (0.1, 0.5)


def _grown(r_cut: np.ndarray, step_m: float, w_m: float) -> np.ndarray:
    """Table g[k] such that g[floor(x / step)] >= max of the bracket lookup over [x - w, x + w]
    (plus w where positive), m; index k over the table plus padding."""
    r = np.asarray(r_cut, dtype=float)
    pair = np.zeros(r.size + 1)
    pair[: r.size - 1] = np.maximum(r[:-1], r[1:])  # lookup(x) = max(r[k], r[k+1]), 0 beyond
    reach = int(math.ceil(w_m / step_m)) + 1
    padded = np.concatenate([np.full(reach, pair[0] if w_m <= 0 else max(pair[0], pair[1])), pair, np.zeros(reach + 1)])
    win = sliding_window_view(padded, 2 * reach + 1).max(axis=1)  # centred window over +- reach
    out = win[: pair.size + reach]
    return np.where(out > 0.0, out + w_m, 0.0)


@dataclass(frozen=True)
class KeepOut:
    """Keep-out of types (a, b) (see module): ``conflict(d)`` for relative vectors d = p_b - p_a."""

    separation_m: float  # without w, m
    w_move_m: float  # tube + sampling inflation, m
    w_rest_m: float  # at rest, m
    step_m: float  # dz step of the tables, m
    a_on_b: np.ndarray  # grown r_cut of a (above) on b (below), moving, m
    b_on_a: np.ndarray  # grown r_cut of b (above) on a (below), moving, m
    a_on_b_rest: np.ndarray
    b_on_a_rest: np.ndarray
    deflection_m: float = 0.0  # the pair's deflections while moving (part of w_move_m), m

    @property
    def reach_xy_m(self) -> float:
        """Largest horizontal distance at which the pair can conflict while moving, m."""
        return self.horizontal_reach_m(rest=False)

    def horizontal_reach_m(self, *, rest: bool) -> float:
        """Largest horizontal distance at which the keep-out (moving, or both at rest) holds a point: the
        sphere's radius separation + w and the widest column, m."""
        below, above = (self.a_on_b_rest, self.b_on_a_rest) if rest else (self.a_on_b, self.b_on_a)
        w = self.w_rest_m if rest else self.w_move_m
        return float(max(self.separation_m + w, below.max(initial=0.0), above.max(initial=0.0)))

    def horizontal_radius_m(self, dz_lo_m: float, dz_hi_m: float) -> float:
        """Largest horizontal distance at which the pair conflicts while moving at some height
        difference d_z = z_b - z_a in [``dz_lo_m``, ``dz_hi_m``], m (at most :attr:`reach_xy_m`):
        the sphere's radius at the smallest |d_z| of the band and the widest cut-off of the table
        rows :meth:`conflict` reads over it (the cut-off below where d_z <= w, above where d_z >= -w)."""
        w = self.w_move_m
        sep = self.separation_m + w
        least = 0.0 if dz_lo_m <= 0.0 <= dz_hi_m else min(abs(dz_lo_m), abs(dz_hi_m))
        out = math.sqrt(sep * sep - least * least) if least < sep else 0.0
        for table, lo, hi in (
            (self.a_on_b, dz_lo_m, min(dz_hi_m, w + 1e-12)),
            (self.b_on_a, max(dz_lo_m, -w - 1e-12), dz_hi_m),
        ):
            if lo > hi:
                continue
            a0 = 0.0 if lo <= 0.0 <= hi else min(abs(lo), abs(hi))
            a1 = max(abs(lo), abs(hi))
            k0, k1 = int(math.floor(a0 / self.step_m)), int(math.floor(a1 / self.step_m))
            if k0 < table.size:
                out = max(out, float(table[k0 : k1 + 1].max()))
        return out

    @property
    def reach_z_m(self) -> float:
        """Largest vertical distance at which the pair can conflict while moving, m."""
        nz = [np.flatnonzero(t > 0) for t in (self.a_on_b, self.b_on_a)]
        top = max([(int(n[-1]) + 2) * self.step_m for n in nz if n.size] + [0.0])
        return float(max(self.separation_m + self.w_move_m, top + self.w_move_m))

    def conflict(self, d: np.ndarray, *, rest: bool = False) -> np.ndarray:
        """(P,) bool for relative vectors ``d`` (P, 3), m."""
        d = np.asarray(d, dtype=float).reshape(-1, 3)
        w = self.w_rest_m if rest else self.w_move_m
        below, above = (self.a_on_b_rest, self.b_on_a_rest) if rest else (self.a_on_b, self.b_on_a)
        r2 = d[:, 0] ** 2 + d[:, 1] ** 2
        dz = d[:, 2]
        sep = self.separation_m + w
        hit = r2 + dz * dz < sep * sep
        k = np.floor(np.abs(dz) / self.step_m).astype(np.int64)
        k_b = np.clip(k, 0, below.size - 1)
        k_a = np.clip(k, 0, above.size - 1)
        rb = np.where(k < below.size, below[k_b], 0.0)
        ra = np.where(k < above.size, above[k_a], 0.0)
        near = np.abs(dz) <= w + 1e-12
        rc = np.where(dz < 0, rb, np.where(dz > 0, ra, 0.0))
        rc = np.where(near, np.maximum(rb, ra), rc)
        return hit | (r2 < rc * rc)


@lru_cache(maxsize=64)
def undamped_radius_m(source, target, *, level: float, rule: str, field_form: str | None, effects: tuple) -> np.ndarray:
    """(K,) per row dz = k * the cut-off table's step (target below the source): the largest
    horizontal distance, m, out to which ``target``'s loop held in ``source``'s jet alone is not
    damped (:func:`search_undamped_radius_m`); the shipped table of the same facts when there is one
    (:mod:`proxplan.planner.swarm.zone_store`, keyed on everything the search depends on:
    :func:`zone_facts`), else searched. Cached per process."""
    from proxplan.planner.swarm.zone_store import facts_key, shipped_zone

    request = dict(source=source, target=target, level=level, rule=rule, field_form=field_form, effects=effects)
    shipped = shipped_zone(facts_key(zone_facts(**request)))
    return shipped if shipped is not None else search_undamped_radius_m(**request)


def default_zone_requests() -> list[dict]:
    """The arguments of :func:`search_undamped_radius_m` whose tables are shipped (:data:`SHIPPED_LEVELS`)."""
    from proxplan.costmaps import effects_key
    from proxplan.physics import BUILTIN_VEHICLES
    from proxplan.planfile import Limits

    rule = Limits().invalid_zone_rule
    vs = [BUILTIN_VEHICLES[n] for n in sorted(BUILTIN_VEHICLES)]
    return [
        dict(source=s, target=t, level=level, rule=rule, field_form=None, effects=effects_key(()))
        for level in SHIPPED_LEVELS
        for s in vs
        for t in vs
    ]


def ship_undamped_zones() -> str:
    """Search the tables of :func:`default_zone_requests` and write them as the shipped file
    (:mod:`proxplan.planner.swarm.zone_store`); its path."""
    from proxplan.planner.swarm.zone_store import facts_key, write_zones

    entries = {}
    for request in default_zone_requests():
        radius = search_undamped_radius_m(**request)
        entries[facts_key(zone_facts(**request))] = {
            "source": request["source"].name,
            "target": request["target"].name,
            "level": request["level"],
            "radius_m": [float(v) for v in radius],
        }
    return str(write_zones(entries))


def zone_facts(source, target, *, level: float, rule: str, field_form: str | None, effects: tuple) -> dict:
    """Everything :func:`search_undamped_radius_m` depends on, as a JSON-able dict (the key of the
    shipped tables): both vehicles' parameters, model options, effects, level, rule, the search's
    constants, the two cut-off tables that bound it (m), the source of the code it runs and NumPy's
    version (:mod:`proxplan.planner.swarm.zone_store`)."""
    import dataclasses
    import inspect

    from proxplan.costmaps import effects_of_key
    from proxplan.physics import ModelOptions, effects_to_list
    from proxplan.planner.checks.constraints import cutoff_table
    from proxplan.planner.swarm.zone_store import code_digest

    def params(v) -> dict:
        return {k: x for k, x in v.to_dict().items() if k not in ("description", "sources")}

    inner = cutoff_table(source, target, level=level, rule=rule, field_form=field_form, effects=effects)
    outer = cutoff_table(
        source, target, level=min(level, UNDAMPED_SCAN_USAGE), rule=rule, field_form=field_form, effects=effects
    )
    options = ModelOptions(field_form=field_form) if field_form else ModelOptions()
    return {
        "source": params(source),
        "target": params(target),
        "options": dataclasses.asdict(options),
        "effects": effects_to_list(effects_of_key(effects)),
        "level": float(level),
        "rule": rule,
        "constants": [UNDAMPED_SCAN_USAGE, UNDAMPED_STEP_M, UNDAMPED_ROW_SAMPLES, list(UNDAMPED_AZIMUTHS_RAD)],
        "cutoff": [inner.dz_step_m, list(inner.r_cut_m), outer.dz_step_m, list(outer.r_cut_m)],
        "code": code_digest(inspect.getsource(search_undamped_radius_m)),
        "numpy": np.__version__,
    }


def search_undamped_radius_m(
    source, target, *, level: float, rule: str, field_form: str | None, effects: tuple
) -> np.ndarray:
    """(K,) per row dz = k * the cut-off table's step (target below the source): the largest
    horizontal distance, m, out to which ``target``'s loop held in ``source``'s jet alone is not
    damped (rightmost pole with real part >= 0, the verifier's test), searched outside the cut-off
    at ``level`` (inside it the keep-out holds anyway) out to the cut-off at
    :data:`UNDAMPED_SCAN_USAGE`, every :data:`UNDAMPED_STEP_M` (or a row's span over
    :data:`UNDAMPED_ROW_SAMPLES`) at :data:`UNDAMPED_AZIMUTHS_RAD`, rounded up by one step; 0 where
    none. A keep-out at a stricter level (a larger cut-off) may take this table of the scenario's
    level: it holds the undamped points outside its own cut-off too. ``rule``, ``field_form``, ``effects``: as
    :func:`proxplan.planner.checks.constraints.cutoff_table`."""
    from proxplan.costmaps import effects_of_key, sources_wrench
    from proxplan.physics import ModelOptions, loop_matrices, loop_poles, wrench_gradient
    from proxplan.planner.checks.constraints import cutoff_table

    inner = cutoff_table(source, target, level=level, rule=rule, field_form=field_form, effects=effects)
    outer = cutoff_table(
        source, target, level=min(level, UNDAMPED_SCAN_USAGE), rule=rule, field_form=field_form, effects=effects
    )
    r_in, r_out = np.asarray(inner.r_cut_m), np.asarray(outer.r_cut_m)
    rows, radii = [], []
    for k in range(1, r_in.size):
        if r_out[k] <= r_in[k]:
            continue
        step = max(UNDAMPED_STEP_M, (r_out[k] - r_in[k]) / UNDAMPED_ROW_SAMPLES)
        r = np.arange(r_in[k], r_out[k] + step, step)
        rows.append(np.full(r.size, k))
        radii.append(np.column_stack([r, np.full(r.size, step)]))
    out = np.zeros(r_in.size)
    if not rows:
        return out
    row, both = np.concatenate(rows), np.concatenate(radii)
    rad, step = both[:, 0], both[:, 1]
    options = ModelOptions(field_form=field_form) if field_form else ModelOptions()
    between = effects_of_key(effects)

    def wrench(rel: np.ndarray) -> tuple[np.ndarray, np.ndarray]:  # rel: target - source, m
        return sources_wrench(target, [(source, rel)], options, between)

    for phi in UNDAMPED_AZIMUTHS_RAD:
        rel = np.column_stack([rad * np.cos(phi), rad * np.sin(phi), -row * inner.dz_step_m])
        force, torque = wrench(rel)
        gf, gt = wrench_gradient(wrench, rel)
        growth = loop_poles(loop_matrices(target, force, torque, gf, gt, reference=False)).growth_ps
        bad = growth >= 0.0
        np.maximum.at(out, row[bad], rad[bad] + step[bad])
    return out


def keepout_for(
    vehicle_a,
    vehicle_b,
    *,
    limits,
    field_form: str | None,
    effects: tuple,
    sample_m: float,
    deflection_m: float = 0.0,
    rest_deflection_m: float | None = None,
    undamped_level: float | None = None,
) -> KeepOut:
    """The :class:`KeepOut` of physics vehicles (a, b) under scenario ``limits``; ``deflection_m``
    (m) grows it while either moves, ``rest_deflection_m`` (m; None: ``deflection_m``) while both
    rest (the two vehicles' predicted deflections: a disturbed vehicle is off its plan at rest too,
    as the verifier counts it, by what it can be there). The zones where the jet undamps
    the target's loop are those of :func:`undamped_radius_m` at ``undamped_level`` (None: the
    authority fraction of ``limits``; a keep-out at a stricter level passes the scenario's, whose
    table it shares)."""
    from proxplan.planner.checks.constraints import cutoff_table

    level = limits.authority_fraction
    ab = cutoff_table(
        vehicle_a, vehicle_b, level=level, rule=limits.invalid_zone_rule, field_form=field_form, effects=effects
    )
    ba = cutoff_table(
        vehicle_b, vehicle_a, level=level, rule=limits.invalid_zone_rule, field_form=field_form, effects=effects
    )
    sep = max(limits.min_separation_m, vehicle_a.body_radius_m + vehicle_b.body_radius_m)
    w_move = float(limits.tracking_margin_m) + sample_m + deflection_m
    w_rest = deflection_m if rest_deflection_m is None else float(rest_deflection_m)
    r_ab, r_ba = np.asarray(ab.r_cut_m), np.asarray(ba.r_cut_m)
    # the zones where the jet undamps the target's loop (module), at the planned relative positions
    fx = dict(
        level=level if undamped_level is None else max(level, undamped_level),
        rule=limits.invalid_zone_rule,
        field_form=field_form,
        effects=effects,
    )
    z_ab = undamped_radius_m(vehicle_a, vehicle_b, **fx)
    z_ba = undamped_radius_m(vehicle_b, vehicle_a, **fx)
    return KeepOut(
        separation_m=float(sep),
        w_move_m=w_move,
        w_rest_m=w_rest,
        step_m=float(ab.dz_step_m),
        a_on_b=_with_zone(_grown(r_ab, ab.dz_step_m, w_move), z_ab, ab.dz_step_m, sample_m),
        b_on_a=_with_zone(_grown(r_ba, ba.dz_step_m, w_move), z_ba, ba.dz_step_m, sample_m),
        a_on_b_rest=_with_zone(_grown(r_ab, ab.dz_step_m, w_rest), z_ab, ab.dz_step_m, sample_m),
        b_on_a_rest=_with_zone(_grown(r_ba, ba.dz_step_m, w_rest), z_ba, ba.dz_step_m, sample_m),
        deflection_m=float(deflection_m),
    )


def _with_zone(grown: np.ndarray, zone: np.ndarray, step_m: float, pad_m: float) -> np.ndarray:
    """The grown cut-off table ``grown`` (m), at least the undamped zone ``zone`` (its radius per dz
    row, m; :func:`undamped_radius_m`) by the same bracket lookup, plus ``pad_m`` (whole-millimetre
    positions), where the zone holds a point. Not grown by the tube or the deflections: the verifier
    judges the loop's poles at the planned positions (:func:`proxplan.verify.jet_loop.loop_along_plan`;
    the tube enters its growth, not its gradients), so the zone is kept out where the plan puts the
    pair."""
    z = _grown(zone, step_m, 0.0)
    z = np.where(z > 0.0, z + pad_m, 0.0)
    out = np.zeros(max(grown.size, z.size))
    out[: grown.size] = grown
    out[: z.size] = np.maximum(out[: z.size], z)
    return out


@dataclass(frozen=True)
class GrownStack:
    """The keep-outs of one type a against every type b, each grown by ``grow_m`` and stacked, so
    that relative vectors of mixed types are tested in one vectorised call (:meth:`conflict`).

    Growing a keep-out by g (the vectors shrunk towards the pair's centre by g horizontally, and
    its sphere by g in 3-D) is, for the cut-off, r - g < r_cut(dz), i.e. r < r_cut(dz) + g where
    r_cut > 0; the shrunk vector's sphere lies inside the grown sphere (triangle inequality), so
    the test is |d| < separation + w + g or r < r_cut(dz) + g: tables of (r_cut + g)^2, squared
    distances, no square root."""

    sphere2: np.ndarray  # (n_b,) (separation + w + g)^2, m^2
    w_m: np.ndarray  # (n_b,) the tube w of the pair (moving or resting), m
    step_m: np.ndarray  # (n_b,) dz step of the pair's tables, m
    below2: np.ndarray  # (n_b, L + 1) (r_cut of a on b below + g)^2, 0 beyond the table, m^2
    above2: np.ndarray  # (n_b, L + 1) (r_cut of b above a + g)^2, m^2
    _cut2: np.ndarray = field(init=False, repr=False, compare=False)  # (3 n_b (L + 1),) m^2: see __post_init__
    _band_m: np.ndarray = field(init=False, repr=False, compare=False)  # (n_b,) w + 1e-12, m
    _step: float | None = field(init=False, repr=False, compare=False)  # the one dz step, m (None: they differ)

    def __post_init__(self) -> None:
        # the three tables a pair reads, flat, one lookup (:meth:`conflict_rz`): [above, below, the
        # larger of the two (within |dz| <= w)] x type b x row k; the bound of the band |dz| <= w; one
        # dz step for every type where they share it (the same division, a scalar)
        both = np.maximum(self.below2, self.above2)
        object.__setattr__(self, "_cut2", np.stack([self.above2, self.below2, both]).ravel())
        object.__setattr__(self, "_band_m", self.w_m + 1e-12)
        step = self.step_m
        object.__setattr__(self, "_step", float(step[0]) if step.size and (step == step[0]).all() else None)

    def conflict(self, d: np.ndarray, tb: np.ndarray) -> np.ndarray:
        """(P,) bool for relative vectors ``d`` (P, 3), m, of vehicles of types ``tb`` (P,)."""
        d = np.asarray(d, dtype=float).reshape(-1, 3)
        return self.conflict_rz(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1], d[:, 2], tb)

    def conflict_rz(self, r2: np.ndarray, dz: np.ndarray, tb: np.ndarray) -> np.ndarray:
        """:meth:`conflict` of relative vectors given as their squared horizontal distances ``r2``
        (P,), m^2, and heights ``dz`` (P,), m (b above a: dz > 0), of types ``tb`` (P,): the same
        tables read in one lookup of the flat stack of [above, below, their larger] (the larger
        within |dz| <= w, else below for dz < 0 and above otherwise), the same booleans."""
        tb = np.asarray(tb, dtype=np.int64)
        adz = np.abs(dz)
        n_b, row = self.below2.shape
        step = self._step if self._step is not None else self.step_m[tb]
        k = np.minimum(np.floor(adz / step).astype(np.int64), row - 1)
        which = np.where(adz <= self._band_m[tb], 2, dz < 0)  # 0 above, 1 below, 2 both
        rc2 = self._cut2.take((which * n_b + tb) * row + k)
        return (r2 + dz * dz < self.sphere2[tb]) | (r2 < rc2)


def grown_stack(keepouts, ta: int, n_types: int, *, rest: bool, grow_m: float) -> GrownStack:
    """The :class:`GrownStack` of type ``ta`` against types 0..``n_types``-1 of ``keepouts``
    ((type a, type b) -> :class:`KeepOut`), at rest or moving, grown by ``grow_m`` (m)."""
    kos = [keepouts[(ta, tb)] for tb in range(n_types)]
    tabs = [(k.a_on_b_rest, k.b_on_a_rest) if rest else (k.a_on_b, k.b_on_a) for k in kos]
    L = max(max(b.size, a.size) for b, a in tabs)

    def padded(t: np.ndarray) -> np.ndarray:
        out = np.zeros(L + 1)
        out[: t.size] = np.where(t > 0.0, (t + grow_m) ** 2, 0.0)
        return out

    w = np.array([k.w_rest_m if rest else k.w_move_m for k in kos])
    return GrownStack(
        sphere2=np.array([(k.separation_m + wk + grow_m) ** 2 for k, wk in zip(kos, w)]),
        w_m=w,
        step_m=np.array([k.step_m for k in kos]),
        below2=np.stack([padded(b) for b, _ in tabs]),
        above2=np.stack([padded(a) for _, a in tabs]),
    )


if __name__ == "__main__":  # pragma: no cover - ships the tables again (zone_store)
    print(ship_undamped_zones())
