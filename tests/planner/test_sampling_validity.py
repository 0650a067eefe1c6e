"""The vectorised validity check (proxplan.planner.checks.validity) against the scalar per-pair check."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.physics import BUILTIN_VEHICLES
from proxplan.planfile import scenario_from_dict
from proxplan.planner.checks.constraints import Track, build_checker
from proxplan.planner.checks.validity import BatchChecker

TYPES = ("crazyflie-2.1", "crazyflie-parrot", "small-quad", "large-quad")


def _scenario():
    return scenario_from_dict(
        {
            "name": "v",
            "workspace": {"min": [-3, -3, 0], "max": [3, 3, 3.5]},
            "obstacles": [{"min": [-0.2, -0.2, 0], "max": [0.2, 0.2, 2.0]}],
            "limits": {"authority_fraction": 0.1, "min_separation_m": 0.25},
            "vehicles": {"me": {"type": "small-quad", "start": [-2, 0, 1], "goal": [2, 0, 1]}},
        }
    )


def _tracks(rng, n):
    out = []
    for i in range(n):
        veh = BUILTIN_VEHICLES[TYPES[i % len(TYPES)]]
        if i % 3 == 0:
            out.append(
                Track.static(f"s{i}", veh, rng.uniform([-2, -2, 0.5], [2, 2, 3.0]), until_s=float(rng.uniform(1, 4)))
            )
        else:
            k = int(rng.integers(2, 120))
            a, b = rng.uniform([-2, -2, 0.5], [2, 2, 3.0], (2, 3))
            f = np.linspace(0, 1, k)[:, None]
            out.append(Track.from_arrays(f"m{i}", veh, 0.05, a + f * (b - a)))
    return out


@pytest.mark.parametrize("mode", ["downwash", "no-downwash", "ellipsoid"])
def test_vectorised_check_matches_the_per_pair_check_on_random_states(mode):
    rng = np.random.default_rng(7)
    sc = _scenario()
    tracks = _tracks(rng, 9)
    checker = build_checker(sc, "me", tracks, mode=mode, margin_m=0.02, until_margin_s=0.2)
    batch = BatchChecker.from_checker(checker)
    # random states, and states close to the tracks so that every kind of conflict occurs
    xyz = rng.uniform([-3.2, -3.2, -0.1], [3.2, 3.2, 3.6], (1500, 3))
    t = rng.uniform(-0.5, 8.0, 1500)
    near_t = rng.uniform(0.0, 6.0, 3000)
    near = np.array([tracks[int(j)].at(float(tt)) for j, tt in zip(rng.integers(0, len(tracks), 3000), near_t)])
    near = near + rng.normal(0.0, [0.25, 0.25, 0.6], (3000, 3))
    xyz, t = np.vstack([xyz, near]), np.concatenate([t, near_t])
    scalar = [checker.conflict(*p, float(tt)) for p, tt in zip(xyz, t)]
    vector = batch.conflicts(xyz, t)
    assert vector == scalar
    kinds = {c.split(" ")[0] for c in scalar if c is not None}
    assert {"workspace", "obstacle[0]", "separation"} <= kinds
    if mode == "downwash":
        assert "downwash" in kinds
    if mode == "ellipsoid":
        assert "ellipsoid" in kinds
    # exclusion of one vehicle and the first-conflict index
    ex = tracks[1].name
    assert batch.conflicts(xyz[:200], t[:200], exclude=ex) == [
        checker.conflict(*p, float(tt), exclude=ex) for p, tt in zip(xyz[:200], t[:200])
    ]
    i, name = batch.first_conflict(xyz, t)
    first = next(k for k, c in enumerate(scalar) if c is not None)
    assert (i, name) == (first, scalar[first])


def test_vectorised_check_without_other_vehicles():
    checker = build_checker(_scenario(), "me", [])
    batch = BatchChecker.from_checker(checker)
    assert batch.first_conflict(np.array([[-2.0, 0.0, 1.0], [0.0, 0.0, 1.0]]), np.array([0.0, 1.0])) == (
        1,
        "obstacle[0]",
    )
