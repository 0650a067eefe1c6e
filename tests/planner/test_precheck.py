"""The one vectorised start/goal check (proxplan.planner.checks.precheck.check_starts_and_goals)
against a plain reference on random crowded scenarios: every pair looked at one by one for the user
mistakes (starts / goals too close, a goal inside another goal's cut-off) and every vehicle through
the scalar ``ConflictChecker`` for the rest, as the two checks it replaces did."""

from __future__ import annotations

import math

import numpy as np
import pytest

from proxplan.costmaps import effects_key
from proxplan.fileio import UserError
from proxplan.planfile import scenario_from_dict
from proxplan.planner import InfeasibleError
from proxplan.planner.checks import Track, build_checker, check_starts_and_goals, cutoff_table

TYPES = ["crazyflie-2.1", "crazyflie-parrot", "small-quad"]


def _random_scenario(rng: np.random.Generator) -> dict:
    n = int(rng.integers(2, 10))
    size = float(rng.uniform(0.8, 3.0))
    lo, hi = np.array([0.0, 0.0, 0.0]), np.array([size, size, 2.5])

    def point(below: list | None = None):
        if below is not None and rng.uniform() < 0.5:  # above / below an earlier point: downwash, ellipsoid
            p = np.asarray(below) + [*rng.normal(0.0, 0.12, 2), rng.choice([-1.0, 1.0]) * rng.uniform(0.2, 1.2)]
            return np.round(np.clip(p, lo + 0.05, hi - 0.05), 3).tolist()
        return np.round(rng.uniform(lo + 0.05, hi - 0.05), 3).tolist()

    vehicles: dict = {}
    for i in range(n):
        earlier = list(vehicles.values())
        pick = earlier[int(rng.integers(len(earlier)))] if earlier else None
        entry: dict = {"type": str(rng.choice(TYPES)), "start": point(pick["start"] if pick else None)}
        roll = rng.uniform()
        if roll < 0.15:
            entry["hover"] = True
        elif roll < 0.25 and i > 0:
            entry["dock"] = {"with": f"v{i - 1}", "offset": [0.0, 0.0, 0.3]}
        else:
            entry["goal"] = point(pick.get("goal") if pick else None)
        vehicles[f"v{i}"] = entry
    for entry in vehicles.values():  # a dock target must end somewhere: give it a goal (not a dock)
        if "dock" in entry:
            target = vehicles[entry["dock"]["with"]]
            target.pop("dock", None)
            if "goal" not in target and "hover" not in target:
                target["goal"] = point()
    return {
        "name": "random",
        "workspace": {"min": lo.tolist(), "max": (hi + [0.0, 0.0, 0.8]).tolist()},
        "limits": {"authority_fraction": float(rng.choice([0.1, 0.3])), "min_separation_m": 0.2},
        "vehicles": vehicles,
    }


def _reference(sc, mode: str):
    """("user", expected text) or ("infeasible", vehicle, constraint) or None."""
    lim, tasks = sc.limits, sc.vehicles
    dock = {frozenset((n, t.dock_with)) for n, t in tasks.items() if t.dock_with is not None}
    sets = {
        "start": [(n, t.start_m) for n, t in tasks.items()],
        "goal": [(n, t.start_m if t.hover else t.goal_m) for n, t in tasks.items() if t.dock_with is None],
    }
    radius = {n: t.vehicle.body_radius_m for n, t in tasks.items()}
    for kind, pts in sets.items():
        for a in range(len(pts)):
            for b in range(a + 1, len(pts)):
                (na, pa), (nb, pb) = pts[a], pts[b]
                if frozenset((na, nb)) in dock:
                    continue
                if math.dist(pa, pb) < max(lim.min_separation_m, radius[na] + radius[nb]):
                    return ("user", f"vehicles.{na}.{kind} and vehicles.{nb}.{kind}:")
    goals = sets["goal"]
    fx = effects_key(getattr(sc, "effects", ()))
    for n_lo, p_lo in goals:  # target below, then source above, in file order
        for n_hi, p_hi in goals:
            dz = float(p_hi[2] - p_lo[2])
            if n_lo == n_hi or dz <= 0.0:
                continue
            table = cutoff_table(
                tasks[n_hi].vehicle,
                tasks[n_lo].vehicle,
                level=lim.authority_fraction,
                rule=lim.invalid_zone_rule,
                field_form=sc.field_form,
                effects=fx,
            )
            if math.dist(p_lo[:2], p_hi[:2]) < table.lookup(dz):
                return ("user", f"vehicles.{n_lo}.goal is inside the downwash cut-off of vehicles.{n_hi}.goal")
    for kind, pts in sets.items():
        for name, p in pts:
            if kind == "goal" and tasks[name].hover:
                continue
            others = [
                Track.static(o, tasks[o].vehicle, q) for o, q in pts if o != name and frozenset((o, name)) not in dock
            ]
            checker = build_checker(sc, name, others, mode=mode, tube=False)
            c = checker.conflict(float(p[0]), float(p[1]), float(p[2]), 0.0)
            if c is not None and c != "workspace" and not c.startswith("obstacle"):
                return ("infeasible", name, c)
    return None


@pytest.mark.parametrize("mode", ["downwash", "no-downwash", "ellipsoid"])
def test_the_vectorised_check_agrees_with_the_pairwise_reference(mode):
    rng = np.random.default_rng(28)
    seen = {"user": 0, "infeasible": 0, None: 0}
    for _ in range(200):
        sc = scenario_from_dict(_random_scenario(rng))
        want = _reference(sc, mode)
        seen[want[0] if want else None] += 1
        if want is None:
            check_starts_and_goals(sc, mode=mode)
        elif want[0] == "user":
            with pytest.raises(UserError) as info:
                check_starts_and_goals(sc, mode=mode)
            assert want[1] in str(info.value), (str(info.value), want)
        else:
            with pytest.raises(InfeasibleError) as err:
                check_starts_and_goals(sc, mode=mode)
            assert (err.value.vehicle, err.value.constraint) == want[1:], (err.value.message, want)
    # every outcome is exercised (without downwash or ellipsoid rules, a start or goal conflict is a
    # separation, always a user mistake)
    assert seen["user"] >= 5 and seen[None] >= 5 and (seen["infeasible"] >= 5 or mode == "no-downwash"), seen


def test_a_start_in_the_workspace_margin_is_left_to_the_planner():
    sc = scenario_from_dict(
        {
            "name": "edge",
            "workspace": {"min": [0, 0, 0], "max": [3, 3, 3]},
            "limits": {"authority_fraction": 0.1, "min_separation_m": 0.2},
            "vehicles": {  # b starts right above a, whose start is within obstacle_margin_m (0.05 m) of the floor
                "a": {"type": "crazyflie-2.1", "start": [1.0, 1.0, 0.01], "goal": [2.0, 2.0, 1.0]},
                "b": {"type": "crazyflie-2.1", "start": [1.0, 1.0, 0.4], "goal": [2.0, 1.0, 1.0]},
            },
        }
    )
    with pytest.raises(InfeasibleError) as err:
        check_starts_and_goals(sc, mode="downwash")
    # a's start is the planner's to name ("workspace"); b's start breaks the cut-off rule on a below it
    assert err.value.vehicle == "b" and err.value.constraint == "downwash on a"
