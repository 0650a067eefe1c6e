"""Independent verifier on hand-made plans: downwash, separation, goals, limits; wrench along a plan."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from proxplan.physics import BUILTIN_VEHICLES, authority_usage, disturbance_wrench
from proxplan.planfile import Plan, VehicleTrajectory, scenario_from_dict
from proxplan.verify import verify_plan, wrench_along_plan

DT = 0.05


def _scenario(low_start, low_goal, *, fraction=0.15, rule="conservative"):
    return scenario_from_dict(
        {
            "name": "hand-made",
            "workspace": {"min": [-3, -3, 0], "max": [3, 3, 3]},
            "limits": {"authority_fraction": fraction, "min_separation_m": 0.3, "invalid_zone_rule": rule},
            "vehicles": {
                "top": {"type": "large-quad", "start": [0, 0, 2.0], "hover": True},
                # the cosine lines below end with an acceleration step: allow their jerk
                "low": {"type": "small-quad", "start": list(low_start), "goal": list(low_goal), "max_jerk_mps3": 15},
            },
        }
    )


def _line(p0, p1, duration_s, *, total_s):
    """Smooth (cosine) rest-to-rest line p0 -> p1 over duration_s, then hold; sampled every DT."""
    t = np.arange(0.0, total_s + DT / 2, DT)
    u = np.clip(t / duration_s, 0.0, 1.0)
    s = 0.5 - 0.5 * np.cos(np.pi * u)
    ds = np.where(u < 1, 0.5 * np.pi / duration_s * np.sin(np.pi * u), 0.0)
    dds = np.where(u < 1, 0.5 * (np.pi / duration_s) ** 2 * np.cos(np.pi * u), 0.0)
    d = np.asarray(p1, float) - np.asarray(p0, float)
    return t, np.asarray(p0, float) + s[:, None] * d, ds[:, None] * d, dds[:, None] * d


def _plan(scenario, low_path):
    t, p, v, a = low_path
    top = scenario.vehicles["top"].start_m
    z = np.zeros_like(p)
    return Plan(
        scenario=scenario.name,
        dt_s=DT,
        vehicles={
            "top": VehicleTrajectory(
                "top", "large-quad", BUILTIN_VEHICLES["large-quad"], t, np.repeat(top[None], t.size, axis=0), z, z
            ),
            "low": VehicleTrajectory("low", "small-quad", BUILTIN_VEHICLES["small-quad"], t, p, v, a),
        },
    )


def test_flying_through_downwash_is_named(tmp_path):
    # straight under the hovering large-quad, 1.2 m below it (valid zone, 3 L = 0.99 m)
    sc = _scenario([-2, 0, 0.8], [2, 0, 0.8], fraction=0.1)
    plan = _plan(sc, _line([-2, 0, 0.8], [2, 0, 0.8], 8.0, total_s=9.0))
    violations = verify_plan(plan, sc)
    kinds = {(v.vehicle, v.kind) for v in violations}
    assert ("low", "authority") in kinds, violations
    auth = next(v for v in violations if v.kind == "authority")
    assert "top" in auth.detail  # the source is named
    assert auth.value > 0.1 and auth.limit == pytest.approx(0.1)
    assert 2.0 < auth.t_s < 5.0  # it happens when passing under the source (t = 4 s)
    assert all(v.kind == "authority" for v in violations)


def test_invalid_zone_is_flagged_unless_rule_is_model():
    path = _line([-2, 0, 1.5], [2, 0, 1.5], 8.0, total_s=9.0)  # 0.5 m under: invalid zone
    sc = _scenario([-2, 0, 1.5], [2, 0, 1.5], fraction=0.9)
    kinds = {v.kind for v in verify_plan(_plan(sc, path), sc)}
    assert "invalid-zone" in kinds
    sc_model = _scenario([-2, 0, 1.5], [2, 0, 1.5], fraction=0.9, rule="model")
    assert "invalid-zone" not in {v.kind for v in verify_plan(_plan(sc_model, path), sc_model)}


def test_clean_detour_passes():
    sc = _scenario([-2, -1.5, 1.0], [2, -1.5, 1.0])
    plan = _plan(sc, _line([-2, -1.5, 1.0], [2, -1.5, 1.0], 8.0, total_s=9.0))
    assert verify_plan(plan, sc) == []


def test_separation_goal_and_speed_violations():
    sc = _scenario([-2, 0, 2.0], [2, -1, 1.0], fraction=0.9)
    # level with the top vehicle straight through it, too fast, ending at the wrong place
    plan = _plan(sc, _line([-2, 0, 2.0], [2, 0, 2.0], 2.0, total_s=3.0))
    kinds = {v.kind for v in verify_plan(plan, sc)}
    assert {"separation", "goal", "speed"} <= kinds


def test_hover_drift_and_missing_vehicle():
    sc = _scenario([-2, -1.5, 1.0], [2, -1.5, 1.0])
    plan = _plan(sc, _line([-2, -1.5, 1.0], [2, -1.5, 1.0], 8.0, total_s=9.0))
    top = plan.vehicles["top"]
    plan.vehicles["top"] = dataclasses.replace(top, position_m=top.position_m + np.array([0.2, 0, 0]))
    assert "hover" in {v.kind for v in verify_plan(plan, sc)}
    del plan.vehicles["top"]
    assert [v.kind for v in verify_plan(plan, sc)] == ["missing"]


def test_wrench_along_plan_is_the_direct_model():
    sc = _scenario([-2, 0, 0.8], [2, 0, 0.8])
    plan = _plan(sc, _line([-2, 0, 0.8], [2, 0, 0.8], 8.0, total_s=9.0))
    t = np.array([1.0, 4.0, 6.5])
    along = wrench_along_plan(plan, sc, t_s=t)
    low_p = plan.vehicles["low"].sample(t)[0]  # grid times: interpolation is exact here
    offsets = low_p - sc.vehicles["top"].start_m
    w = disturbance_wrench(BUILTIN_VEHICLES["large-quad"], BUILTIN_VEHICLES["small-quad"], offsets)
    np.testing.assert_allclose(along["low"].force_N, w.force_N, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(
        along["low"].usage, authority_usage(BUILTIN_VEHICLES["small-quad"], w.force_N, w.torque_Nm), rtol=1e-9
    )
    assert along["low"].usage[1] > along["low"].usage[0]  # strongest right under the source
    np.testing.assert_allclose(along["top"].force_N, 0.0)  # nothing above the top vehicle


def test_dock_pair_is_exempt_only_on_the_approach_tube():
    sc = scenario_from_dict(
        {
            "name": "dock",
            "workspace": {"min": [-3, -3, 0], "max": [3, 3, 3]},
            "limits": {"authority_fraction": 0.5},
            "vehicles": {
                "top": {"type": "large-quad", "start": [0, 0, 1.5], "hover": True},
                "low": {
                    "type": "small-quad",
                    "start": [0, 0, 2.5],
                    "dock": {"with": "top", "offset": [0, 0, 0.3]},
                    "max_jerk_mps3": 15,  # the cosine line ends with an acceleration step
                },
            },
        }
    )
    # straight down the dock axis: exempt, passes
    plan = _plan(sc, _line([0, 0, 2.5], [0, 0, 1.8], 4.0, total_s=5.0))
    assert verify_plan(plan, sc) == []
    # sideways through the target's level, then to the dock point: separation is flagged
    t1, p1, v1, a1 = _line([-1.5, 0, 1.5], [1.5, 0, 1.5], 6.0, total_s=6.0)
    t2, p2, v2, a2 = _line([1.5, 0, 1.5], [0, 0, 1.8], 4.0, total_s=5.0)
    path = (
        np.concatenate([t1, t2[1:] + t1[-1]]),
        np.concatenate([p1, p2[1:]]),
        np.concatenate([v1, v2[1:]]),
        np.concatenate([a1, a2[1:]]),
    )
    kinds = {v.kind for v in verify_plan(_plan(sc, path), sc)}
    assert "separation" in kinds


def _beside_scenario(fraction, tube):
    return scenario_from_dict(
        {
            "name": "beside",
            "workspace": {"min": [-3, -3, 0], "max": [3, 3, 3]},
            "limits": {"authority_fraction": fraction, "min_separation_m": 0.3, "tracking_margin_m": tube},
            "vehicles": {
                "top": {"type": "large-quad", "start": [0, 0, 2.0], "hover": True},
                "low": {"type": "small-quad", "start": [-2, 0.5, 0.8], "goal": [2, 0.5, 0.8], "max_jerk_mps3": 15},
            },
        }
    )


def test_authority_is_checked_within_the_tracking_tube():
    # passing 0.5 m beside the large-quad's axis, 1.2 m below it: set the limit between the usage on
    # the plan and the usage 0.06 m closer to the axis
    path = _line([-2, 0.5, 0.8], [2, 0.5, 0.8], 8.0, total_s=9.0)
    large, small = BUILTIN_VEHICLES["large-quad"], BUILTIN_VEHICLES["small-quad"]
    on_plan = authority_usage(small, *_wrench(large, small, [0.0, 0.5, -1.2]))
    closer = authority_usage(small, *_wrench(large, small, [0.0, 0.44, -1.2]))
    assert closer > 1.2 * on_plan > 0.0
    limit = float(0.5 * (on_plan + closer)[0])
    plain = _beside_scenario(limit, 0.0)
    assert verify_plan(_plan(plain, path), plain) == []
    tubed = _beside_scenario(limit, 0.06)
    kinds = {v.kind for v in verify_plan(_plan(tubed, path), tubed)}
    assert kinds == {"authority-tube"}


def _wrench(source, target, offset):
    w = disturbance_wrench(source, target, np.array([offset], dtype=float))
    return w.force_N, w.torque_Nm


def _source_sets_sample_by_sample(name, w, pos, m):
    """jet_loop._source_sets as it was before round 13C: one key per sample."""
    from proxplan.verify.jet_loop import MIN_DZ_M, WEAK_USAGE

    names = sorted(w.usage_by_source)
    which = np.stack([w.usage_by_source[s] >= WEAK_USAGE for s in names]) if names else np.zeros((0, m), bool)
    others = [o for o in pos if o != name]
    above = np.stack([pos[o][:, 2] - pos[name][:, 2] > MIN_DZ_M for o in others]) if others else np.zeros((0, m), bool)
    groups: dict = {}
    for k in np.flatnonzero(w.usage >= WEAK_USAGE):
        key = tuple(s for s, on in zip(names, which[:, k]) if on) or tuple(
            o for o, on in zip(others, above[:, k]) if on
        )
        if key:
            groups.setdefault(key, []).append(int(k))
    return {key: np.asarray(rows) for key, rows in groups.items()}


@pytest.mark.parametrize("case", ["three-high-stack", "pillar-8", "circle-8", "random-10"])
def test_the_jets_source_sets_grouped_at_once_are_those_sample_by_sample(case):
    """The sets of sources whose jets act together on a vehicle (for its loop's gradients), grouped
    over all samples at once, are the per-sample grouping's: the same sets, the same samples
    (circle-8 and random-10 hold samples where only the sources above together reach WEAK_USAGE)."""
    import gzip
    import json
    from pathlib import Path

    from proxplan.planfile import plan_from_dict
    from proxplan.verify import scenario_of_plan
    from proxplan.verify.jet_loop import _source_sets

    path = Path(__file__).resolve().parent / "reference" / f"{case}.plan.json.gz"
    with gzip.open(path, "rt", encoding="utf-8") as f:
        plan = plan_from_dict(json.load(f), label=case)
    sc = scenario_of_plan(plan, label=case)
    t = np.arange(0.0, float(plan.t_s[-1]) + 0.005, 0.01)
    pos = plan.positions_at(t)
    seen = 0
    for name, w in wrench_along_plan(plan, sc, t_s=t).items():
        want = _source_sets_sample_by_sample(name, w, pos, t.size)
        got = _source_sets(name, w, pos, t.size)
        assert sorted(got) == sorted(want), (case, name)
        for key in want:
            assert np.array_equal(got[key], want[key]), (case, name, key)
        seen += len(want)
    assert seen > 0  # some vehicle is in a jet that matters


def test_the_verifiers_deflections_are_the_planners_allowance() -> None:
    """verify_with_deflections returns verify_plan's violations and the loops' deflections it ran, which give
    the planners' deflection allowance exactly as predicting them again does (the pipeline no longer runs the
    loops twice on a rejected plan)."""
    import gzip
    import json
    from pathlib import Path

    from proxplan.planfile import plan_from_dict
    from proxplan.planner.metrics import DEFLECTION_DT_S, deflection_allowance
    from proxplan.verify import scenario_of_plan, verify_with_deflections

    reference = Path(__file__).resolve().parent / "reference"
    checked = 0
    for path in sorted(reference.glob("*.plan.json.gz")):
        with gzip.open(path, "rt", encoding="utf-8") as f:
            plan = plan_from_dict(json.load(f), label=path.name)
        scenario = scenario_of_plan(plan, label=path.name)
        bad, deflections = verify_with_deflections(plan, scenario, dt_fine_s=DEFLECTION_DT_S)
        assert [str(v) for v in bad] == [str(v) for v in verify_plan(plan, scenario)]
        again = deflection_allowance(plan, scenario)
        assert deflection_allowance(plan, scenario, deflections=deflections) == again
        checked += bool(again)
    assert checked >= 1  # at least one reference plan has a vehicle pushed off its plan
