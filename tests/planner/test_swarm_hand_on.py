"""A swarm plan hands on what it computed (SwarmInfo.hand_on) and ``swarm_again`` plans with other
options from it (its own tracks re-timed through waypoints, the give-up plans on its problem): the
same tracks as planning afresh with those options; the hand-on stays out of the plan's metrics."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from proxplan.planfile import scenario_from_dict
from proxplan.planner.formations import formation_change, grid_reshuffle
from proxplan.planner.swarm import SwarmOptions, swarm_timed
from proxplan.planner.swarm.plan import swarm_again

# the pipeline's options for ``optimized`` with fixed goals: 3 + OPTIMIZE_EXTRA_PASSES re-timing passes
OPTIONS = SwarmOptions(seed=0, passes=8, reserve_starts=True)


def _samples(timed: dict) -> dict:
    end_s = max(p.duration_s for p in timed.values())
    t_s = np.arange(0.0, end_s + 0.005, 0.01)
    return {name: (np.asarray(p.knot_t_s), p.sample(t_s)[0]) for name, p in timed.items()}


def _assert_same(a: dict, b: dict) -> None:
    sa, sb = _samples(a), _samples(b)
    assert sa.keys() == sb.keys()
    for name in sb:
        np.testing.assert_array_equal(sa[name][0], sb[name][0])
        np.testing.assert_array_equal(sa[name][1], sb[name][1])


@pytest.mark.parametrize(
    ("layout", "n", "fields"),
    [
        (grid_reshuffle, 8, {"through_waypoints": "retime"}),  # prioritised, with the both-wavefronts pass
        (grid_reshuffle, 8, {"prioritized": False}),  # the give-up plans on the fast plan's problem
        (formation_change, 12, {"through_waypoints": "retime"}),  # the stacked plan re-timed again
        (grid_reshuffle, 8, {"deflection_m": {"v000": 0.01}}),  # another problem: planned afresh
    ],
)
def test_planning_again_from_the_hand_on_gives_the_tracks_of_planning_afresh(layout, n, fields):
    scenario = scenario_from_dict(layout(n), label="test scenario")
    _, info = swarm_timed(scenario, OPTIONS)
    assert info.hand_on is not None and info.hand_on.options == OPTIONS
    other = replace(OPTIONS, **fields)
    again, again_info = swarm_again(scenario, info.hand_on, other)
    fresh, fresh_info = swarm_timed(scenario, other)
    _assert_same(again, fresh)
    assert again_info.stage == fresh_info.stage
    assert again_info.makespan_s == fresh_info.makespan_s
    assert again_info.hand_on is not None and again_info.hand_on.options == other


def test_the_hand_on_carries_the_both_wavefronts_pass_where_it_gave_other_tracks():
    """grid-8 fixed: the pass with both wavefronts gives other tracks (so the re-timing path above
    re-times and compares them too); the plan's metrics hold no hand-on and stay JSON."""
    scenario = scenario_from_dict(grid_reshuffle(8), label="test scenario")
    _, info = swarm_timed(scenario, OPTIONS)
    assert info.stage == "prioritised"
    assert info.hand_on is not None and info.hand_on.heights is not None
    metrics = info.to_metrics()
    assert "hand_on" not in metrics
    assert json.loads(json.dumps(metrics))["makespan_s"] == info.makespan_s
