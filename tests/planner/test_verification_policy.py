"""The pipeline's one verification policy (planner.pipeline._until_verified): a rejected plan is
planned again with grown tubes, then with another seed, except where the plan cannot depend on the
seed (the swarm layer's prioritised plans): that attempt would plan the same again."""

from __future__ import annotations

import pytest

import proxplan.planner.pipeline as pipeline
import proxplan.verify as verify


class _Plan:
    def __init__(self, seed: int, grown: bool):
        self.seed, self.grown, self.notes = seed, grown, []


@pytest.mark.parametrize(("seed_matters", "attempts"), [(None, 3), (lambda p: True, 3), (lambda p: False, 2)])
def test_another_seed_only_where_the_plan_depends_on_it(monkeypatch, seed_matters, attempts):
    monkeypatch.setattr(verify, "verify_plan", lambda plan, scenario: ["a violation"])  # every plan rejected
    monkeypatch.setattr(verify, "verify_with_deflections", lambda plan, scenario, **_: (["a violation"], {}))
    monkeypatch.setattr(pipeline, "deflection_allowance", lambda plan, scenario, **_: {"v0": 0.01})
    made = []

    def attempt(deflection, seed):
        made.append((dict(deflection), seed))
        return _Plan(seed, bool(deflection))

    run = pipeline._start("swarm", 5, None, None, None, None, None)
    plan, bad = pipeline._until_verified(None, run, attempt, seed_matters=seed_matters)
    assert bad == ["a violation"]
    assert len(made) == attempts
    assert made[:2] == [({}, 5), ({"v0": 0.01}, 5)]
    if attempts == 3:
        assert made[2] == ({"v0": 0.01}, 5 + pipeline.RETRY_SEED_OFFSET)
    else:
        assert any("not tried" in n for n in plan.notes)


class _Info:
    def __init__(self, stage: str):
        self.stage, self.coordination = stage, f"{stage} plan"


@pytest.mark.parametrize(("stage", "prioritized"), [("lattice", [True, False, False]), ("prioritised", [True, True])])
def test_prioritised_planning_not_run_again_where_it_gave_up(monkeypatch, stage, prioritized):
    """The swarm layer's re-plans after a rejected plan: prioritised planning, which gave up (the
    lattice plan) and does not draw on the seed, is not run again with keep-outs no narrower (issue
    37 round 13B); where it gave the plan, every attempt runs it."""
    monkeypatch.setattr(verify, "verify_plan", lambda plan, scenario: ["a violation"])  # every plan rejected
    monkeypatch.setattr(verify, "verify_with_deflections", lambda plan, scenario, **_: (["a violation"], {}))
    monkeypatch.setattr(pipeline, "deflection_allowance", lambda plan, scenario, **_: {"v0": 0.01})
    monkeypatch.setattr(pipeline, "swarm_applicable", lambda scenario: None)
    calls = []

    def swarm_timed(scenario, options, **kw):
        calls.append((options.prioritized, dict(options.deflection_m), options.seed))
        return {}, _Info(stage)

    monkeypatch.setattr(pipeline, "swarm_timed", swarm_timed)
    monkeypatch.setattr(pipeline, "assemble_plan", lambda scenario, timed, method, notes: _Plan(0, False))

    class _Scenario:
        load_notes: list[str] = []

    run = pipeline._start("swarm", 5, None, None, None, None, None)
    out = pipeline._swarm_stage(_Scenario(), run)
    assert out.plan is None and "failed verification" in (out.why_not or "")
    assert [c[0] for c in calls] == prioritized
    assert calls[0][1] == {} and all(c[1] == {"v0": 0.01} for c in calls[1:])


def test_no_narrower():
    assert pipeline._no_narrower({}, {})
    assert pipeline._no_narrower({"a": 0.01}, {"a": 0.01, "b": 0.02})
    assert not pipeline._no_narrower({"a": 0.02}, {"a": 0.01})
    assert not pipeline._no_narrower({"a": 0.01}, {"b": 0.01})
