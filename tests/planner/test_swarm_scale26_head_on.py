"""The head-on count of benchmarks/why_128.py (``--level``; round 26B, docs/planner.md "Stop 64, round 26B"):
vehicles flying opposite ways along one line are counted, parallel or distant lines are not."""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import why_128  # noqa: E402

from proxplan.planfile import scenario_from_dict  # noqa: E402
from proxplan.planner.formations import LAYOUTS  # noqa: E402
from proxplan.planner.swarm import swarm_problem  # noqa: E402


def test_corridor_columns_are_head_on_pairs():
    # corridor-4: two columns (y = -0.3, +0.3 m, 0.6 m apart), each one vehicle west and one east trading
    # sides along the same line: 2 ordered head-on pairs per column, 2 vehicles on one line
    problem = swarm_problem(scenario_from_dict(LAYOUTS["corridor"](4), label="corridor-4"))
    assert problem.reach_xy_m < 0.6  # the other column is out of reach (else this count would be 8)
    assert why_128.head_on(problem) == (4, 2)


def test_same_way_and_distant_lines_are_not_head_on():
    problem = swarm_problem(scenario_from_dict(LAYOUTS["corridor"](4), label="corridor-4"))
    starts, goals = problem.starts_m.copy(), problem.goals_m.copy()
    east = [a for a in range(4) if goals[a, 0] > starts[a, 0]]
    west = [a for a in range(4) if a not in east]
    starts[west], goals[west] = goals[west].copy(), starts[west].copy()  # every vehicle now flies east
    assert why_128.head_on(replace(problem, starts_m=starts, goals_m=goals))[0] == 0
    far = problem.starts_m.copy(), problem.goals_m.copy()
    shift = np.array([0.0, 2.0 * problem.reach_xy_m + 1.0, 0.0])
    moved_s, moved_g = far[0].copy(), far[1].copy()
    moved_s[west] += shift  # the westbound vehicles on lines beyond reach of the eastbound ones
    moved_g[west] += shift
    assert why_128.head_on(replace(problem, starts_m=moved_s, goals_m=moved_g))[0] == 0
