"""Round 29S: late vehicles of the passing stage that hem one another in pass together
(``hemmed.merged_group``), and a late vehicle with no line, corner or arc flies a wavefront route
(``hemmed.late_track``): corridor-64 by type 1.89 B -> 1.33 B."""

from __future__ import annotations

import numpy as np
import pytest

from proxplan.planfile import scenario_from_dict
from proxplan.planner.formations import layout_doc
from proxplan.planner.swarm import hemmed
from proxplan.planner.swarm.goals import apply_assignment
from proxplan.planner.swarm.options import SwarmOptions
from proxplan.planner.swarm.plan import swarm_timed
from proxplan.planner.swarm.problem import swarm_problem


@pytest.fixture(scope="module")
def corridor64():
    scenario, record = apply_assignment(scenario_from_dict(layout_doc("corridor", 64, assign="by_type")))
    return scenario, swarm_problem(scenario), float(record["lower_bound_s"])


def test_merged_group_only_late_free_lines(corridor64, monkeypatch) -> None:
    _, problem, _ = corridor64
    names = problem.names
    v029, v037, v039, v001 = (names.index(n) for n in ("v029", "v037", "v039", "v001"))
    yes = lambda group: True  # noqa: E731
    assert hemmed.merged_group(problem, v029, {v037, v039}, {v029, v037, v039}, [], yes) == (v029, v037, v039)
    # only the late ones among those hemming it in join it; none late: no group
    assert hemmed.merged_group(problem, v029, {v037, v039}, {v029, v037}, [], yes) == (v029, v037)
    assert hemmed.merged_group(problem, v029, {v037, v039}, {v029}, [], yes) is None
    # a line through the wall (v001) is never in a group; nor a group there already, nor one without a move
    assert hemmed.merged_group(problem, v029, {v001}, {v029, v001}, [], yes) is None
    assert hemmed.merged_group(problem, v029, {v037}, {v029, v037}, [(v029, v037)], yes) is None
    assert hemmed.merged_group(problem, v029, {v037}, {v029, v037}, [], lambda group: False) is None
    monkeypatch.setattr(hemmed, "MERGE_HEMMING", False)
    assert hemmed.merged_group(problem, v029, {v037}, {v029, v037}, [], yes) is None


def _plan(scenario):
    paths, info = swarm_timed(scenario, SwarmOptions(reserve_starts=False))
    return paths, info.makespan_s


@pytest.mark.slow
def test_corridor64_by_type_passes_together(corridor64, monkeypatch) -> None:
    """The passing stage's plan of corridor-64 by type: 1.33 B (1.89 B, prioritised planning's, before),
    the same twice; without the merged groups the plan in hand stands."""
    scenario, _, bound_s = corridor64
    paths, makespan_s = _plan(scenario)
    assert makespan_s < 1.5 * bound_s
    again, makespan2_s = _plan(scenario)
    assert makespan2_s == makespan_s
    for name, path in paths.items():
        assert np.array_equal(path.knot_t_s, again[name].knot_t_s)
    monkeypatch.setattr(hemmed, "MERGE_HEMMING", False)
    _, without_s = _plan(scenario)
    assert without_s > 1.7 * bound_s
