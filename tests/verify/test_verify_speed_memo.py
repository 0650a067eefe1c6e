"""The verifier gives back its answer for the plan it checked last (proxplan.verify.memo, stop 61
round 23A): asked again about the same plan (the same scenario, trajectories and step) it returns the
answer it computed, equal to computing it afresh; any change to what it reads (a sample, the fine
step, another scenario object) computes again; and what a caller does to the answer it got does not
reach the next caller."""

from __future__ import annotations

import dataclasses

import numpy as np

from proxplan.verify import checks, verify_plan, verify_with_deflections
from proxplan.verify.memo import VerifyMemo, plan_key

from . import test_verify as hand_made

LOW_START_M, LOW_GOAL_M = (-1.5, 0.0, 0.8), (1.5, 0.0, 0.8)


def _scenario():
    return hand_made._scenario(LOW_START_M, LOW_GOAL_M)


def _plan(scenario, duration_s=3.0, total_s=4.0):
    """The small quad on a cosine line under the hovering large quad (its jet reaches it)."""
    return hand_made._plan(scenario, hand_made._line(LOW_START_M, LOW_GOAL_M, duration_s, total_s=total_s))


def _same(a, b) -> bool:
    (va, da), (vb, db) = a, b
    return va == vb and sorted(da) == sorted(db) and all(np.array_equal(da[n], db[n]) for n in da)


def test_the_same_plan_again_is_given_back_equal_to_computing_it():
    sc = _scenario()
    first = verify_with_deflections(_plan(sc), sc)
    hits = checks.LAST.hits
    again = verify_with_deflections(_plan(sc), sc)  # another Plan object, the same content
    assert checks.LAST.hits == hits + 1
    assert _same(first, again)
    assert first[1] and any(float(d.max()) > 0.0 for d in first[1].values())  # the loops ran: a real answer
    fresh = checks._verified(_plan(sc), sc, 0.01)
    assert _same(again, fresh)
    assert verify_plan(_plan(sc), sc) == fresh[0]


def test_a_change_to_what_it_reads_computes_again():
    sc = _scenario()
    plan = _plan(sc)
    base = verify_with_deflections(plan, sc)
    moved = _plan(sc)
    low = moved.vehicles["low"]
    pos = low.position_m.copy()
    pos[10, 2] -= 0.5  # one sample dropped half a metre: inconsistent with its velocity
    moved.vehicles["low"] = dataclasses.replace(low, position_m=pos)
    misses = checks.LAST.misses
    got = verify_with_deflections(moved, sc)
    assert checks.LAST.misses == misses + 1
    assert _same(got, checks._verified(moved, sc, 0.01))
    assert got[0] != base[0]
    # another fine step, another scenario object with the same content: computed again
    for args in ((plan, sc, 0.02), (plan, _scenario(), 0.01)):
        misses = checks.LAST.misses
        verify_with_deflections(args[0], args[1], dt_fine_s=args[2])
        assert checks.LAST.misses == misses + 1


def test_what_a_caller_changes_does_not_reach_the_next():
    sc = _scenario()
    memo = VerifyMemo()
    plan = _plan(sc)
    violations, loops = memo.get(plan, sc, 0.01, lambda: checks._verified(plan, sc, 0.01))
    want = checks._verified(plan, sc, 0.01)
    violations.append("not a violation")
    for d in loops.values():
        d[:] = -1.0
    again = memo.get(plan, sc, 0.01, lambda: (_ for _ in ()).throw(AssertionError("computed again")))
    assert memo.hits == 1 and memo.misses == 1
    assert _same(again, want)


def test_the_key_sees_every_array_and_the_order():
    sc = _scenario()
    plan = _plan(sc)
    key = plan_key(plan, 0.01)
    assert plan_key(_plan(sc), 0.01) == key
    low = plan.vehicles["low"]
    for field in ("velocity_mps", "acceleration_mps2"):
        arr = getattr(low, field).copy()
        arr[5, 0] += 1e-12
        changed = dataclasses.replace(plan, vehicles={**plan.vehicles, "low": dataclasses.replace(low, **{field: arr})})
        assert plan_key(changed, 0.01) != key
    swapped = dataclasses.replace(plan, vehicles={"low": plan.vehicles["low"], "top": plan.vehicles["top"]})
    assert plan_key(swapped, 0.01) != key
    assert plan_key(plan, 0.02) != key


def test_a_scenario_changed_in_place_is_not_the_one_answered_for():
    sc = _scenario()
    plan = _plan(sc)
    verify_with_deflections(plan, sc)
    task = sc.vehicles["low"]
    sc.vehicles["low"] = dataclasses.replace(task, goal_m=task.goal_m + np.array([0.0, 0.5, 0.0]))
    misses = checks.LAST.misses
    got = verify_with_deflections(plan, sc)
    assert checks.LAST.misses == misses + 1
    assert any(v.kind.startswith("goal") for v in got[0])  # the moved goal is not reached
