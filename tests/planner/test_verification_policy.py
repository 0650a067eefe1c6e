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
    monkeypatch.setattr(pipeline, "deflection_allowance", lambda plan, scenario: {"v0": 0.01})
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
